#version 330 core
// Highlight pass: the cut stroke as world-space line segments drawn over the final image.
uniform mat4 view_proj;
in vec3 in_position;
void main() {
    gl_Position = view_proj * vec4(in_position, 1.0);
}
