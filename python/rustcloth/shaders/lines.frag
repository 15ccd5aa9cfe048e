#version 330 core
// Highlight pass: flat colour so the stroke reads against any shading.
uniform vec4 color;
out vec4 f_color;
void main() { f_color = color; }
