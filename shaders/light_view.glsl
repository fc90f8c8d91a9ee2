// light_view.glsl — light-view, cascade and grid arithmetic shared by the
// passes that run after light_setup's frame step: the CPU twin's
// `LightSetup::{to_light_view, rotate, microquad_grid_box}`,
// `CascadeGrid::{grid_coords, ndc_of_grid, cell_index}`, `cascades::
// cascade_of_depth` and `bin::{cell_range, place}`, same operation order.
// Include after declaring `FrameParams frame` and `LightState light`.
// Grid functions take the cascade `k` whose grid they work in.
#define LIGHT_VIEW_GLSL

// footprint::CELL_PADDING: cell rectangles grow by 1/64 cell on every side, far
// above the f32 rounding of a grid coordinate.

// rotation · (p − origin); `precise` keeps the compiler from fusing
// multiply-adds the CPU does not fuse.
vec3 to_light_view(vec3 p) {
    precise vec3 q = p - light.origin;
    precise vec3 r = vec3(dot(light.rot_x, q), dot(light.rot_y, q), dot(light.rot_z, q));
    return r;
}

vec3 rotate(vec3 v) {
    precise vec3 r = vec3(dot(light.rot_x, v), dot(light.rot_y, v), dot(light.rot_z, v));
    return r;
}

// The cascade of an eye-relative receiver position (LightSetup::cascade_of).
// Computed once per pixel by light_setup's extent step, which stores it for
// the later passes (see light_setup.comp): every pass then agrees on it.
uint cascade_of(vec3 p) {
    precise float depth = dot(p, frame.cam_forward);
    for (uint k = 0u; k + 1u < light.cascade_count; ++k) {
        if (depth <= light.split[k]) return k;
    }
    return max(light.cascade_count, 1u) - 1u;
}

vec2 grid_size(uint k) {
    return vec2(float(light.cascade[k].cells_x), float(light.cascade[k].cells_y));
}

vec2 grid_coords(uint k, vec2 ndc) {
    return (ndc - light.cascade[k].ndc_min) / (light.cascade[k].ndc_max - light.cascade[k].ndc_min)
        * grid_size(k);
}

vec2 ndc_of_grid(uint k, vec2 g) {
    return light.cascade[k].ndc_min + g / grid_size(k) * (light.cascade[k].ndc_max - light.cascade[k].ndc_min);
}

// light_setup::level_side: cells along one side of pyramid level l.
uint level_side(uint side, uint l) {
    return side == 0u ? 0u : ((side - 1u) >> l) + 1u;
}

uvec2 level_dims(uint k, uint l) {
    return uvec2(level_side(light.cascade[k].cells_x, l), level_side(light.cascade[k].cells_y, l));
}

// CascadeGrid::level_offset: the levels lie back to back, finest first.
uint level_offset(uint k, uint l) {
    uint offset = light.cascade[k].cell_offset;
    for (uint j = 0u; j < l; ++j) {
        uvec2 d = level_dims(k, j);
        offset += d.x * d.y;
    }
    return offset;
}

// CascadeGrid::cell_index_at (level_start = level_offset(k, l)).
uint cell_index_at(uint k, uint level_start, uint l, uint x, uint y) {
    return level_start + y * level_side(light.cascade[k].cells_x, l) + x;
}

uint cell_index(uint k, uint x, uint y) {
    return light.cascade[k].cell_offset + y * light.cascade[k].cells_x + x;
}

vec2 ndc_of(vec3 q) {
    return light.projection == 0u ? q.xy : q.xy / q.z;
}

// Grid-space box of the µQuad's projected corners (eye-relative p, ex, ey).
void microquad_grid_box(uint k, vec3 p, vec3 ex, vec3 ey, out vec2 lo, out vec2 hi) {
    vec3 hx = ex * 0.5, hy = ey * 0.5;
    vec3 corners[4] = vec3[4](p - hx - hy, p + hx - hy, p + hx + hy, p - hx + hy);
    lo = vec2(1.0 / 0.0);
    hi = vec2(-1.0 / 0.0);
    [[unroll]] for (int c = 0; c < 4; ++c) {
        vec2 g = grid_coords(k, ndc_of(to_light_view(corners[c])));
        lo = min(lo, g);
        hi = max(hi, g);
    }
}

// footprint::cell_range_in: inclusive cells (x0, y0, x1, y1) of the
// padded box in a dims grid, or false when it misses the grid (or is NaN,
// or the grid has no cells).
bool cell_range_in(uvec2 dims, vec2 lo, vec2 hi, out uvec4 cells) {
    lo -= CELL_PADDING;
    hi += CELL_PADDING;
    float w = float(dims.x), h = float(dims.y);
    cells = uvec4(0u);
    if (hi.x < 0.0 || hi.y < 0.0 || lo.x >= w || lo.y >= h || isnan(lo.x) || isnan(hi.x)) return false;
    uint x0 = uint(max(lo.x, 0.0)), y0 = uint(max(lo.y, 0.0));
    cells = uvec4(x0, y0, max(uint(min(hi.x, w - 1.0)), x0), max(uint(min(hi.y, h - 1.0)), y0));
    return true;
}

// footprint::cell_range: level 0 of cascade k.
bool cell_range(uint k, vec2 lo, vec2 hi, out uvec4 cells) {
    return cell_range_in(uvec2(light.cascade[k].cells_x, light.cascade[k].cells_y), lo, hi, cells);
}

// footprint::cell_range_at: the range at level l of a level-0 box (scaled
// by 2^-l with ldexp, exact like the CPU's multiplication).
bool cell_range_at(uint k, uint l, vec2 lo, vec2 hi, out uvec4 cells) {
    ivec2 e = ivec2(-int(l));
    return cell_range_in(level_dims(k, l), ldexp(lo, e), ldexp(hi, e), cells);
}
