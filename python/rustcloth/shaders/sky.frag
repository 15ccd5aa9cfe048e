#version 330 core
// Software tier, sky: drawn after the forward pass at the far plane, so only the pixels no
// surface covered pay for it. The same sky as the lighting pass's.
uniform mat4 inv_view_proj;
uniform vec3 eye;
uniform vec3 sky_zenith;    // linear
uniform vec3 sky_horizon;
uniform float exposure;

in vec2 v_uv;
out vec4 f_color;

#include "tonemap.glsl"

void main() {
    vec4 world = inv_view_proj * vec4(v_uv * 2.0 - 1.0, 1.0, 1.0);
    vec3 dir = normalize(world.xyz / world.w - eye);
    f_color = vec4(srgb_encode(tonemap(sky(dir) * exposure)) + dither8(gl_FragCoord.xy), 1.0);
}
