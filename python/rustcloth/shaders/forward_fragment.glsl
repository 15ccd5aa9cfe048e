// Software tier, forward pass, fragment stage (forward.frag: every surface but the cloth;
// forward_cloth.frag: the cloth, TWO_SIDED): each surface shaded as it is drawn, for renderers without a
// GPU (llvmpipe), where every full-screen pass and every byte of a G-buffer costs CPU time
// per pixel. Per pixel: the same fabric and tiles as the full tier, one hardware-filtered
// shadow tap, fog, tone mapping; the light comes per vertex from forward.vert (Lambert, a
// rim sheen for the Charlie lobe, Blinn-Phong for GGX, the same sky ambient and point
// lights). No SSAO, no FXAA.

uniform int material;
uniform vec3 base_color;   // linear; static meshes and markers
uniform bool front_is_winding;
uniform vec2 cloth_size;   // m along i and j
uniform sampler2DShadow shadow_map;
uniform bool shadows_enabled;
uniform vec3 sky_zenith;    // linear
uniform vec3 sky_horizon;
uniform float exposure;

in vec3 v_world;
in vec3 v_shadow;
in vec3 v_diffuse_a;
in vec3 v_key_a;
in vec3 v_gloss_a;
#ifdef TWO_SIDED
in vec2 v_uv;
in vec3 v_diffuse_b;
in vec3 v_key_b;
in vec3 v_gloss_b;
#endif
in vec4 v_fog;
out vec4 f_color;

#include "materials.glsl"
#include "tonemap.glsl"

float shadow_factor() {
    if (!shadows_enabled) return 1.0;
    vec3 s = v_shadow;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    return texture(shadow_map, vec3(s.xy, s.z - 0.0015));  // one tap, 2x2 by the hardware
}

void main() {
    vec3 albedo = base_color;
#ifdef TWO_SIDED
    // The side the vertex normal faces is the triangles' front.
    albedo = fabric(v_uv, gl_FrontFacing == front_is_winding);
    vec3 diffuse = gl_FrontFacing ? v_diffuse_a : v_diffuse_b;
    vec3 key = gl_FrontFacing ? v_key_a : v_key_b;
    vec3 gloss = gl_FrontFacing ? v_gloss_a : v_gloss_b;
#else
    if (material == MAT_FLOOR) {
        albedo = floor_color(v_world.xz);
    } else if (material == MAT_MARKER || material == MAT_LIGHT) {
        float strength = material == MAT_MARKER ? MAT_MARKER_EMISSIVE : MAT_LIGHT_EMISSIVE;
        f_color = vec4(srgb_encode(tonemap(albedo * strength)) + dither8(gl_FragCoord.xy), 1.0);
        return;
    }
    vec3 diffuse = v_diffuse_a, key = v_key_a, gloss = v_gloss_a;
#endif
    vec3 color = albedo * diffuse;
    if (dot(key, key) + dot(gloss, gloss) > 0.0) {
        color += (albedo * key + gloss) * shadow_factor();
    }
    color = mix(color, v_fog.rgb, v_fog.a);
    f_color = vec4(srgb_encode(tonemap(color * exposure)) + dither8(gl_FragCoord.xy), 1.0);
}
