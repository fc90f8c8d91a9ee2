// watertight_ray.glsl — the watertight ray/triangle test shared by the
// passes that trace rays through the BVH (gbuffer, shadow_rays): the CPU
// twin's `WatertightRay` in f32.
//
// Woop, Benthin, Wald (JCGT 2013): the ray is sheared so that it runs
// along +z through its origin, and the 2D edge functions of the
// sheared vertices decide the hit. A shared edge's function is the same
// products of the same floats in both triangles (`precise`: no fused
// multiply-add may differ between them), so a ray through a seam hits one
// of the two triangles or both, never neither (Möller–Trumbore can miss
// both and report whatever lies behind the seam).
struct ShearedRay {
    int kx, ky, kz;
    vec3 shear;
};

ShearedRay sheared_ray(vec3 d) {
    vec3 a = abs(d);
    int kz = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    int kx = (kz + 1) % 3;
    int ky = (kx + 1) % 3;
    if (d[kz] < 0.0) {
        int swap = kx;
        kx = ky;
        ky = swap;
    }
    return ShearedRay(kx, ky, kz, vec3(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]));
}

// Ray parameter of the hit along the ray's direction from `org`, or −1
// (the vertices are taken relative to `org` first: exact for org = 0).
float hit_triangle(Triangle t, vec3 org, ShearedRay r) {
    precise vec3 a = t.a - org, b = t.b - org, c = t.c - org;
    precise float ax = a[r.kx] - r.shear.x * a[r.kz];
    precise float ay = a[r.ky] - r.shear.y * a[r.kz];
    precise float bx = b[r.kx] - r.shear.x * b[r.kz];
    precise float by = b[r.ky] - r.shear.y * b[r.kz];
    precise float cx = c[r.kx] - r.shear.x * c[r.kz];
    precise float cy = c[r.ky] - r.shear.y * c[r.kz];
    precise float u = cx * by - cy * bx;
    precise float v = ax * cy - ay * cx;
    precise float w = bx * ay - by * ax;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) return -1.0;
    precise float det = u + v + w;
    if (det == 0.0) return -1.0;   // the ray runs in the triangle's plane
    precise float t_scaled = r.shear.z * (u * a[r.kz] + v * b[r.kz] + w * c[r.kz]);
    return t_scaled / det;
}

