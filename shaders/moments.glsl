// moments.glsl — the filtered maps' lookups, the GPU twin of
// `baseline::moments::{moments_lookup, exponential, chebyshev, hamburger}`: the blurred
// moments filtered bilinearly at the receiver, then Chebyshev's bound with
// light-bleeding reduction (VSM; Donnelly & Lauritzen 2006, Lauritzen
// 2007), the Hamburger 4MSM reconstruction (Peters & Klein 2015) or the
// exponential test (ESM; Annen et al. 2008). Same
// operation order as the CPU, every product `precise`. Include in
// shadow_lookup.comp after texel_of and texel_world.

// ESM (Annen et al. 2008): the filtered exp(c·(u − 1)) times exp(c·(1 − z)),
// z taken at 0 in front of the range.
float exponential(float mean, float z) {
    precise float e = MAP_FILTER_ESM_EXPONENT * (1.0 - max(z, 0.0));
    precise float lit = mean * exp(e);
    return clamp(lit, 0.0, 1.0);
}

float chebyshev(float mean, float square, float z, float min_sigma) {
    if (z <= mean) return 1.0;
    precise float variance = max(square - mean * mean, min_sigma * min_sigma);
    precise float d = z - mean;
    precise float p = variance / (variance + d * d);
    precise float cut = (p - MAP_FILTER_BLEEDING_CUT) / (1.0 - MAP_FILTER_BLEEDING_CUT);
    return clamp(cut, 0.0, 1.0);
}

// Shadow intensity (occluded share) of a receiver at moment depth z.
float hamburger(float m[4], float z) {
    float a = MAP_FILTER_MOMENT_BIAS;
    precise float b[4];
    [[unroll]] for (int i = 0; i < 4; ++i) b[i] = (1.0 - a) * m[i] + a * 0.5;
    precise float l32_d22 = -b[0] * b[1] + b[2];
    precise float d22 = -b[0] * b[0] + b[1];
    precise float squared_variance = -b[1] * b[1] + b[3];
    precise float d33_d22 = squared_variance * d22 - l32_d22 * l32_d22;
    precise float inv_d22 = 1.0 / d22;
    precise float l32 = l32_d22 * inv_d22;
    precise float c[3] = float[3](1.0, z, z * z);
    c[1] -= b[0];
    c[2] -= b[1] + l32 * c[1];
    c[1] *= inv_d22;
    c[2] *= d22 / d33_d22;
    c[1] -= l32 * c[2];
    c[0] -= c[1] * b[0] + c[2] * b[1];
    precise float p = c[1] / c[2];
    precise float q = c[0] / c[2];
    precise float r = sqrt(max(p * p * 0.25 - q, 0.0));
    precise float z1 = -p * 0.5 - r;
    precise float z2 = -p * 0.5 + r;
    float s0, s1, s2, s3;
    if (z2 < z) {
        s0 = z1; s1 = z; s2 = 1.0; s3 = 1.0;
    } else if (z1 < z) {
        s0 = z; s1 = z1; s2 = 0.0; s3 = 1.0;
    } else {
        return 0.0;
    }
    precise float quotient = (s0 * z2 - b[0] * (s0 + z2) + b[1]) / ((z2 - s1) * (z - z1));
    precise float shadow = s2 + s3 * quotient;
    return isnan(shadow) ? 0.0 : clamp(shadow, 0.0, 1.0);
}

float moments_lookup(uint k, vec2 origin, vec2 texel, vec3 p, vec2 ndc) {
    uint side = frame.map_side, n = moment_count(), texels = map_texels();
    uint start = texels + texels * n + k * side * side * n;
    precise vec2 t = texel_coords(origin, texel, ndc) - 0.5;
    vec2 base = floor(t);
    precise vec2 f = t - base;
    ivec2 b = texel_of(base);
    precise float w[4] = float[4]((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    ivec2 d[4] = ivec2[4](ivec2(0, 0), ivec2(1, 0), ivec2(0, 1), ivec2(1, 1));
    precise float m[4] = float[4](0.0, 0.0, 0.0, 0.0);
    for (int q = 0; q < 4; ++q) {
        ivec2 tx = b + d[q];
        bool inside = tx.x >= 0 && tx.y >= 0 && tx.x < int(side) && tx.y < int(side);
        for (uint c = 0u; c < n; ++c) {
            float v = inside ? shadow_map[start + (uint(tx.y) * side + uint(tx.x)) * n + c] : 1.0;
            m[c] += w[q] * v;
        }
    }
    vec2 moment_range = moment_depth_range();
    float own = moment_of_distance(moment_range, light_distance(p));
    precise float bias = texel_world(texel, p) * CONSTANT_BIAS_TEXELS / moment_range.y;
    precise float z = own - bias;
    if (n == 1u) return exponential(m[0], z);
    return n == 2u ? chebyshev(m[0], m[1], z, bias) : 1.0 - hamburger(m, z);
}
