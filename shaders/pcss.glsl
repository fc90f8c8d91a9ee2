// pcss.glsl — percentage-closer soft shadows (Fernando 2005), the GPU twin
// of `baseline::pcss::pcss`: blocker search over PCSS_BLOCKER_DISK scaled
// to the light projected toward the map's near end, penumbra half-width
// from the blockers' mean distance, PCF over PCSS_FILTER_DISK scaled to it;
// both radii clamped to [1, PCSS_MAX_RADIUS_TEXELS] texels of the finer
// axis. Same operation order as the CPU, every product `precise`.
// Include in shadow_lookup.comp after stored, texel_of and texel_world.

// The receiver plane's distance at texel tx's centre, never beyond the
// receiver (the pcf filter's receiver-plane bias).
float pcss_receiver(vec2 origin, vec2 texel, ivec2 tx, vec3 p, vec3 n, float own) {
    float receiver = plane_distance(texel_centre(origin, texel, tx), p, n);
    return finite(receiver) ? min(receiver, own) : own;
}

float pcss(uint k, vec2 origin, vec2 texel, vec3 position, vec3 p, vec3 n, vec2 ndc) {
    float own = light_distance(p);
    precise float bias = texel_world(texel, p) * CONSTANT_BIAS_TEXELS;
    vec2 t = texel_coords(origin, texel, ndc);
    float finer = min(texel.x, texel.y);
    precise float cap = finer * float(PCSS_MAX_RADIUS_TEXELS);
    // 1. Blocker search radius (Fernando 2005's similar triangles).
    precise float search;
    if (light.projection == 0u) {
        precise float span = frame.map_near - dot3(light.rot_z, position);
        search = frame.map_light_size * max(span, 0.0);
    } else {
        precise float zn = light.receiver_z[0] * MAP_NEAR_RATIO;
        precise float num = frame.map_light_size * (p.z - zn);
        search = num / (p.z * zn);
    }
    search = min(max(search, finer), cap);
    vec2 scale = vec2(search) / texel;
    precise float sum = 0.0;
    uint count = 0u;
    for (uint i = 0u; i < PCSS_BLOCKER_TAPS; ++i) {
        precise vec2 s = t + PCSS_BLOCKER_DISK[i] * scale;
        ivec2 tx = texel_of(floor(s));
        float st = stored(k, tx);
        if (isinf(st)) continue;
        float receiver = pcss_receiver(origin, texel, tx, p, n, own);
        precise float limit = st + bias;
        if (limit < receiver) {
            sum += st;
            count += 1u;
        }
    }
    if (count == 0u) return 1.0;
    float blocker = sum / float(count);
    // 2. Penumbra half-width, light NDC.
    precise float radius;
    if (light.projection == 0u) {
        radius = frame.map_light_size * (own - blocker);
    } else {
        precise float num = frame.map_light_size * (own - blocker);
        radius = num / (blocker * own);
    }
    radius = min(max(radius, finer), cap);
    // 3. Percentage-closer filter over that disk.
    scale = vec2(radius) / texel;
    uint lit = 0u;
    for (uint i = 0u; i < PCSS_FILTER_TAPS; ++i) {
        precise vec2 s = t + PCSS_FILTER_DISK[i] * scale;
        ivec2 tx = texel_of(floor(s));
        float st = stored(k, tx);
        if (isinf(st)) {
            lit += 1u;
            continue;
        }
        float receiver = pcss_receiver(origin, texel, tx, p, n, own);
        precise float limit = st + bias;
        lit += receiver <= limit ? 1u : 0u;
    }
    return float(lit) / float(PCSS_FILTER_TAPS);
}
