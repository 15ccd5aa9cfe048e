#version 330 core
// Overlay pass: a screen-space quad (pixel rectangle given as NDC bounds) for the text panel.
uniform vec4 rect;  // x0, y0, x1, y1 in NDC
out vec2 v_uv;
void main() {
    vec2 c = vec2(gl_VertexID & 1, (gl_VertexID >> 1) & 1);
    v_uv = c;  // the panel arrives bottom row first, as GL textures are stored
    gl_Position = vec4(mix(rect.xy, rect.zw, c), 0.0, 1.0);
}
