// entry_normal.glsl — G-buffer entry i's camera-facing unit normal: its
// own (B_G_NORMAL) where the host's depth and normal made it (id
// DEPTH_SURFACE, `gbuffer_from_depth.comp`), else its triangle's
// (B_TRIANGLE_NORMALS, negated when its word has FLAG_NORMAL_FLIPPED).
// The CPU twin keeps a normal per entry (`GBuffer::normal`). Include after
// common.glsl and both bindings.
vec3 entry_normal(uint i, uint word) {
    uint id = gbuffer_triangle(word);
    return id == DEPTH_SURFACE ? g_normal[i] : receiver_normal(triangle_normals[id], word);
}
