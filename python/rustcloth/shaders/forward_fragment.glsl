// Software tier, forward pass, fragment stage (forward.frag: every surface but the cloth;
// forward_cloth.frag: the cloth, TWO_SIDED): each surface shaded as it is drawn, for renderers
// without a GPU (llvmpipe), where every full-screen pass, every byte of a G-buffer, every
// varying and every texture tap costs CPU time per pixel. Per pixel: the same fabric and
// tiles as the full tier, under the light and fog that forward.vert computed per vertex;
// on the floor and the solids, one hardware-filtered shadow tap; tone mapping. No SSAO, no
// FXAA.

uniform int material;
uniform vec3 base_color;   // linear; static meshes and markers
uniform bool front_is_winding;
uniform vec3 eye;
uniform vec2 cloth_size;   // m along i and j
uniform vec3 sky_zenith;    // linear
uniform vec3 sky_horizon;
uniform float exposure;
uniform vec3 key_color;     // linear, times its intensity
uniform sampler2DShadow shadow_map;
uniform bool shadows_enabled;

in vec3 v_light_a;
in vec3 v_add_a;
#ifdef TWO_SIDED
in vec2 v_uv;
in vec3 v_light_b;
in vec3 v_add_b;
in vec3 v_position;
flat in vec3 v_flat_normal;
flat in int v_sliver;
#else
in vec2 v_key_a;
in vec3 v_shadow;
in vec2 v_floor;
#endif
out vec4 f_color;

#include "materials.glsl"
#include "tonemap.glsl"

#ifndef TWO_SIDED
float shadow_factor() {
    if (!shadows_enabled) return 1.0;
    vec3 s = v_shadow;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    return texture(shadow_map, vec3(s.xy, s.z - 0.0015));  // one tap, 2x2 by the hardware
}
#endif

void main() {
    vec3 albedo = base_color;
#ifdef TWO_SIDED
    // The side the vertex normal faces is the triangles' front. Which side the viewer sees
    // the winding says, unless the triangle winds against its vertex normals (a sliver along
    // a cut whose cut vertices crossed): then the normals say, as in geometry.frag; on a
    // sliver the renderer marked, the side its cut vertex's normal faces toward the eye.
    vec3 to_viewer = cross(dFdx(v_position), dFdy(v_position));
    bool against = dot(v_flat_normal, gl_FrontFacing ? to_viewer : -to_viewer) < 0.0;
    bool seen = v_sliver != 0 ? dot(v_flat_normal, eye - v_position) >= 0.0
                              : gl_FrontFacing != against;
    albedo = fabric(v_uv, seen == front_is_winding);
    vec3 color = albedo * (seen ? v_light_a : v_light_b) + (seen ? v_add_a : v_add_b);
#else
    if (material == MAT_FLOOR) {
        albedo = floor_color(v_floor);
    } else if (material == MAT_MARKER || material == MAT_LIGHT) {
        float strength = material == MAT_MARKER ? MAT_MARKER_EMISSIVE : MAT_LIGHT_EMISSIVE;
        f_color = vec4(srgb_encode(tonemap(albedo * strength)) + dither8(gl_FragCoord.xy), 1.0);
        return;
    }
    vec3 color = albedo * v_light_a + v_add_a
               + key_color * (shadow_factor() * (albedo * v_key_a.x + v_key_a.y));
#endif
    f_color = vec4(srgb_encode(tonemap(color)) + dither8(gl_FragCoord.xy), 1.0);
}
