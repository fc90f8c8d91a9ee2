// camera.glsl — the camera's projection for the passes that rasterise or
// march in screen space: the GPU twin of `baseline::screen_frame::ScreenFrame::
// {view_depth, framebuffer}`. Clip space has reversed depth near / s
// (infinite far); x, y put pixel centres at integer + ½ of the viewport.
// Same operation order as the CPU.

float view_depth(vec3 q) {
    return dot3(q, frame.cam_forward);
}

vec4 camera_clip(vec3 q) {
    precise float s = view_depth(q);
    precise vec3 r = q - frame.cam_corner * s;
    precise float cx = dot3(r, frame.cam_dx) / dot3(frame.cam_dx, frame.cam_dx) * (2.0 / float(frame.width)) - s;
    precise float cy = dot3(r, frame.cam_dy) / dot3(frame.cam_dy, frame.cam_dy) * (2.0 / float(frame.height)) - s;
    return vec4(cx, cy, frame.near, s);
}

// The framebuffer position the rasteriser's division and viewport give.
vec2 camera_framebuffer(vec3 q) {
    vec4 c = camera_clip(q);
    precise vec2 ndc = c.xy / c.w;
    float w = float(frame.width), h = float(frame.height);
    precise vec2 f = vec2(ndc.x * (w * 0.5) + w * 0.5, ndc.y * (h * 0.5) + h * 0.5);
    return f;
}
