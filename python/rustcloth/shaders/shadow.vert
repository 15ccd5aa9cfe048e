#version 330 core
// Shadow pass: depth from the directional light; everything that casts goes through here.
uniform mat4 light_view_proj;
uniform mat4 model;
in vec3 in_position;
void main() {
    gl_Position = light_view_proj * model * vec4(in_position, 1.0);
}
