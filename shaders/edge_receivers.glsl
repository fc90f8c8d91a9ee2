// edge_receivers.glsl — the edge pixels' extra surfaces as receivers
// (`izb::gbuffer::edge_surfaces`): what `cpu::evaluate::evaluate_wanted`
// and `LightSetup::receiver_boxes` know of them.
//
// A frame with edge surfaces keeps them as more rows of the G-buffer:
// entry width × height + k is extra surface k, whose pixel's samples it
// covers are B_EDGE_COVERAGE[k]; a pixel's own entry covers the samples
// on its centre's surface (its record's x, edge_pixel_record). Include after declaring
// `FrameParams frame`; receiver_grid_box comes with light_view.glsl
// included first.

layout(scalar, binding = B_EDGE_PIXELS) readonly buffer EdgePixelBuf { uint edge_pixel_words[]; };
layout(scalar, binding = B_EDGE_COVERAGE) readonly buffer EdgeCoverageBuf { uint edge_coverage[]; };

// The mask half this shader forms (evaluate.comp's MASK_HALF_HIGH: MODE_PAIRED64's
// samples 32–63, whose µQuad pattern has edge surfaces of its own).
#ifdef MASK_HALF_HIGH
#define EDGE_HALF 1u
#else
#define EDGE_HALF 0u
#endif

// Words of B_EDGE_PIXELS' tile table, before the records.
uint edge_table_words() {
    uint tiles_x = (frame.width + WORKGROUP_PIXELS_X - 1u) / WORKGROUP_PIXELS_X;
    uint tiles_y = (frame.height + WORKGROUP_PIXELS_Y - 1u) / WORKGROUP_PIXELS_Y;
    return EDGE_TILE_WORDS * tiles_x * tiles_y;
}

// Pixel i's tile in the table and its bit there (8y + x within the tile).
uvec2 edge_tile_bit(uint i) {
    uint x = i % frame.width, y = i / frame.width;
    uint tiles_x = (frame.width + WORKGROUP_PIXELS_X - 1u) / WORKGROUP_PIXELS_X;
    uint tile = (y / WORKGROUP_PIXELS_Y) * tiles_x + x / WORKGROUP_PIXELS_X;
    return uvec2(tile, (y % WORKGROUP_PIXELS_Y) * WORKGROUP_PIXELS_X + x % WORKGROUP_PIXELS_X);
}

// Pixel i's record index r + 1, or 0 for a pixel without one: its tile's
// first record plus the tile's records before its bit.
uint edge_record_link(uint i) {
    uvec2 tb = edge_tile_bit(i);
    uint at = EDGE_TILE_WORDS * tb.x;
    uint lo = edge_pixel_words[at], hi = edge_pixel_words[at + 1u];
    uint bit = tb.y;
    uint word = bit < 32u ? lo : hi;
    uint below = (1u << (bit & 31u)) - 1u;
    if (((word >> (bit & 31u)) & 1u) == 0u) return 0u;
    uint before = bit < 32u ? uint(bitCount(lo & below)) : uint(bitCount(lo) + bitCount(hi & below));
    return 1u + edge_pixel_words[at + 2u] + before;
}

// Pixel i's record for mask half `mask_half` (centre coverage, counted, facing
// away, first extra surface | count << EDGE_COUNT_SHIFT): only edge pixels
// keep one, found through their tile (B_EDGE_PIXELS), 4 words per half;
// the rest see all their samples on their centre's surface. A pixel's
// extra surfaces of both halves are consecutive, each covering samples of
// its own half only (edge_coverage: a word per surface and half).
uvec4 edge_pixel_record(uint i, uint mask_half) {
    uint r = edge_record_link(i);
    if (r == 0u) return uvec4(FULL_MASK, FULL_MASK, 0u, 0u);
    uint at = edge_table_words() + 4u * (frame.mask_halves * (r - 1u) + mask_half);
    return uvec4(edge_pixel_words[at], edge_pixel_words[at + 1u],
                 edge_pixel_words[at + 2u], edge_pixel_words[at + 3u]);
}

// The samples of half `mask_half` extra surface k covers.
uint surface_coverage(uint k, uint mask_half) {
    return edge_coverage[k * frame.mask_halves + mask_half];
}

// The samples receiver i must test (evaluate's `wanted`): its coverage in
// a frame with edge surfaces, every sample otherwise.
uint receiver_wanted(uint i) {
    if (frame.edge_surfaces == 0u) return FULL_MASK;
    uint pixels = frame.width * frame.height;
    return i < pixels ? edge_pixel_record(i, EDGE_HALF).x : surface_coverage(i - pixels, EDGE_HALF);
}

#ifdef LIGHT_VIEW_GLSL
// LightSetup::receiver_boxes: the grid box of receiver i's µQuad (p, ex,
// ey), or with `covered_boxes` of the part of it its covered samples span
// (`pair_pattern` is the µQuad's sample pattern in every frame)
// (light_setup::covered_rectangle, grown by COVERED_MARGIN), in the CPU
// twin's operation order.
void receiver_grid_box(uint k, uint i, vec3 p, vec3 ex, vec3 ey, out vec2 lo, out vec2 hi) {
    uint c = frame.covered_boxes != 0u ? receiver_wanted(i) : FULL_MASK;
    if (c == FULL_MASK || c == 0u) {
        microquad_grid_box(k, p, ex, ey, lo, hi);
        return;
    }
    vec2 s_lo = vec2(1.0), s_hi = vec2(0.0);
    [[unroll]] for (uint s = 0u; s < 32u; ++s) {
        if ((c & (1u << s)) != 0u) {
            s_lo = min(s_lo, frame.pair_pattern[s]);
            s_hi = max(s_hi, frame.pair_pattern[s]);
        }
    }
    s_lo = max(s_lo - COVERED_MARGIN, vec2(0.0));
    s_hi = min(s_hi + COVERED_MARGIN, vec2(1.0));
    precise vec2 centre = (s_lo + s_hi) * 0.5 - vec2(0.5);
    precise vec2 size = s_hi - s_lo;
    precise vec3 q = p + centre.x * ex + centre.y * ey;
    precise vec3 qx = ex * size.x;
    precise vec3 qy = ey * size.y;
    microquad_grid_box(k, q, qx, qy, lo, hi);
}
#endif
