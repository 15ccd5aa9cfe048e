#version 330 core
// Full-screen passes: one oversized triangle from gl_VertexID, so no vertex buffer is needed.
uniform float ndc_depth;  // 0 (the default) for most; 1 puts the sky behind everything
out vec2 v_uv;
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    v_uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, ndc_depth, 1.0);
}
