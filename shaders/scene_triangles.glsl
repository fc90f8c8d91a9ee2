// scene_triangles.glsl — the scene's triangles as the GPU holds them
// (`SceneUpload`): three indices per triangle into a table of distinct
// eye-relative vertices. Courtyard's 877 380 triangles share 641 957
// vertices, so the table and indices take 20.8 bytes per triangle against
// 36 for three vertices each; a triangle's vertices are the same floats
// either way, so every pass's results are unchanged bit for bit.

#ifndef SCENE_TRIANGLES_GLSL
#define SCENE_TRIANGLES_GLSL

layout(scalar, binding = B_TRIANGLES) readonly buffer TriBuf { TriangleCorners triangle_corners[]; };
layout(scalar, binding = B_VERTICES) readonly buffer VertexBuf { vec3 vertices[]; };

Triangle scene_triangle(uint id) {
    TriangleCorners c = triangle_corners[id];
    return Triangle(vertices[c.a], vertices[c.b], vertices[c.c]);
}

#endif
