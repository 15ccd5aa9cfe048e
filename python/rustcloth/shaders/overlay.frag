#version 330 core
// Overlay pass: a text or legend panel rasterised by Pillow, alpha-blended over the frame.
uniform sampler2D text;
in vec2 v_uv;
out vec4 f_color;
void main() { f_color = texture(text, v_uv); }
