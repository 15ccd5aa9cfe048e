#version 330 core
// Geometry pass: world-space attributes for the G-buffer. Cloth, floor, spheres, colliders
// and the markers share this program; `model` places the static meshes.
uniform mat4 view_proj;
uniform mat4 model;
uniform vec3 eye;
uniform float depth_push;  // m (see depth_push.glsl)
uniform int first_cut_vertex;  // the cloth's vertices from here on lie on cuts

in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
in float in_scalar;

out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out float v_scalar;
out float v_push;  // m further along the view ray the depth was written
// A sliver along a cut whose winding disagrees with its vertex normals: the renderer marks
// it by ending it on a cut vertex (the provoking one), any other triangle on a particle.
flat out int v_sliver;

#include "depth_push.glsl"

void main() {
    vec4 world = model * vec4(in_position, 1.0);
    v_world = world.xyz;
    // Models are rotation, translation and uniform scale, so the upper 3x3 transforms
    // normals correctly.
    v_normal = mat3(model) * in_normal;
    v_uv = in_uv;
    v_scalar = in_scalar;
    v_sliver = gl_VertexID >= first_cut_vertex ? 1 : 0;
    v_push = pushed_by(world.xyz, normalize(v_normal));
    gl_Position = depth_pushed(view_proj * world, world.xyz, v_push);
}
