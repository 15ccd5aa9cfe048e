// Software tier, forward pass, vertex stage (forward.vert: every surface but the cloth;
// forward_cloth.vert: the cloth, TWO_SIDED): all the lighting and the fog are computed per
// vertex and interpolated (Gouraud), folded into as few terms as a pixel can take them in:
// on llvmpipe every varying and every texture tap is paid per pixel. The cloth's shadow is
// per vertex too (its particle grid is fine enough for it); the floor's cells grow to metres
// far away, too coarse for the edge of a shadow, so the floor and the solids look theirs up
// per pixel, in one hardware-filtered tap. The meshes are fine enough for the light: the
// cloth's particle grid, a sphere of 2,048 quads, and a floor cut into a grid that is fine
// near the scene and coarse far away. Each side of a surface gets its own terms (thin cloth
// shows whichever faces the viewer).
uniform mat4 view_proj;
uniform mat4 model;
uniform mat4 light_view_proj;
uniform int material;
uniform bool front_is_winding;  // the cloth's front side is the triangles' front face
uniform int first_cut_vertex;  // the cloth's vertices from here on lie on cuts
uniform vec3 eye;
uniform vec3 key_dir;       // direction the key light travels, unit
uniform vec3 key_color;     // linear, times its intensity
uniform vec3 sky_zenith;    // linear
uniform vec3 sky_horizon;
uniform vec3 ground_color;
uniform float ambient;
uniform int num_points;
uniform vec3 point_pos[MAX_POINT_LIGHTS];
uniform vec3 point_color[MAX_POINT_LIGHTS];  // linear, times the intensity
uniform float point_reach[MAX_POINT_LIGHTS];
uniform vec2 fog_range;     // m from the eye where fog starts and where it is complete
uniform float exposure;
uniform sampler2DShadow shadow_map;
uniform bool shadows_enabled;
uniform float shadow_texel; // 1 / the shadow map's size
uniform float depth_push;   // m (see depth_push.glsl)

in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;

// What a pixel shows before tone mapping, for the side the normal faces (a) and, for the
// cloth, the other (b): albedo * v_light + v_add, and on the one-sided surfaces the key light
// on top, times its shadow: key_color * shadow * (albedo * v_key.x + v_key.y). v_light: the
// light that falls on the albedo (ambient, point lights; on the cloth the key light too,
// shadowed); v_add: the cloth's sheen (shadowed) and the fog; v_key: the key light's diffuse
// and gloss factors (white light: scalars). All times the exposure and the fog's complement.
out vec3 v_light_a;
out vec3 v_add_a;
#ifdef TWO_SIDED
out vec2 v_uv;
out vec3 v_light_b;
out vec3 v_add_b;
// For the side a triangle shows where its winding disagrees with its vertex normals (see
// forward_fragment.glsl): the position, whose screen derivatives give the face's normal, and
// the provoking vertex's normal, not interpolated.
out vec3 v_position;
flat out vec3 v_flat_normal;
flat out int v_sliver;  // a sliver wound against its normals (geometry.vert)
#else
out vec2 v_key_a;
out vec3 v_shadow;  // shadow-map coordinates in [0, 1] (x, y, depth)
out vec2 v_floor;   // world x, z: where the floor's tiles are
#endif

#include "tonemap.glsl"
#include "depth_push.glsl"

// What the side with normal n shows, unshadowed, unfogged: the light on the albedo from the
// ambient (diffuse; the caller adds the point lights), and the key light's: on the albedo
// (key) and added (gloss).
void side(vec3 n, vec3 p, vec3 v, bool cloth, bool front, out vec3 diffuse, out vec3 key,
          out vec3 gloss) {
    vec3 l = -key_dir;
    float n_l = dot(n, l);
    vec3 hemi = mix(ground_color, 0.5 * (sky_zenith + sky_horizon), 0.5 + 0.5 * n.y);
    diffuse = ambient * hemi;
    gloss = vec3(0.0);
    if (cloth) {
        // Lambert and 12 % of the light through from behind, as the full tier's thin
        // cloth, and a sheen that brightens towards grazing view in place of its lobe.
        vec3 sheen = front ? MAT_CLOTH_FRONT_SHEEN : MAT_CLOTH_BACK_SHEEN;
        float rim = 1.0 - max(dot(n, v), 0.0);
        key = key_color * (n_l > 0.0 ? n_l : -0.12 * n_l);
        gloss = n_l > 0.0 ? sheen * (rim * rim) * n_l * key_color : vec3(0.0);
    } else {
        key = key_color * max(n_l, 0.0);
        float roughness = material == MAT_FLOOR ? MAT_FLOOR_ROUGHNESS
                        : material == MAT_COLLIDER ? MAT_COLLIDER_ROUGHNESS
                        : MAT_SPHERE_ROUGHNESS;
        float alpha = max(roughness * roughness, 0.01);
        float power = 2.0 / (alpha * alpha) - 2.0;  // Blinn-Phong for GGX
        float n_h = max(dot(n, normalize(l + v)), 0.0);
        if (n_l > 0.0) gloss = vec3(0.04 * (power + 8.0) / 8.0 * pow(n_h, power) * n_l) * key_color;
    }
}

// The point lights' irradiance at p on the side normal n faces (facing) and on the other
// (away): one loop for both sides of the cloth.
void point_lights(vec3 n, vec3 p, out vec3 facing, out vec3 away) {
    facing = away = vec3(0.0);
    for (int i = 0; i < num_points; ++i) {
        vec3 d = point_pos[i] - p;
        float dist2 = dot(d, d);
        float r2 = point_reach[i] * point_reach[i];
        float window = max(1.0 - (dist2 / r2) * (dist2 / r2), 0.0);
        float pn_l = dot(n, d) * inversesqrt(dist2);
        vec3 e = point_color[i] * (window * window / (dist2 + 0.01));
        facing += e * max(pn_l, 0.0);
        away += e * max(-pn_l, 0.0);
    }
}

// The key light's visibility for the cloth at shadow-map coordinates s: 3 x 3
// hardware-filtered taps a texel and a half apart, so that it stays smooth interpolated
// across the cloth's triangles.
float key_visibility(vec3 s) {
    if (!shadows_enabled) return 1.0;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    float lit = 0.0;
    for (int i = -1; i <= 1; ++i) {
        for (int j = -1; j <= 1; ++j) {
            vec2 o = vec2(i, j) * (1.5 * shadow_texel);
            lit += textureLod(shadow_map, vec3(s.xy + o, s.z - 0.0015), 0.0);
        }
    }
    return lit / 9.0;
}

void main() {
    vec4 world = model * vec4(in_position, 1.0);
    vec3 p = world.xyz;
    vec3 n = normalize(mat3(model) * in_normal);  // rotation, translation, uniform scale
    vec3 l = -key_dir;
    // Looked up from just off the surface on the light's side, as the lighting pass does.
    vec4 lp = light_view_proj * vec4(p + n * (dot(n, l) >= 0.0 ? 0.01 : -0.01), 1.0);
    vec3 shadow_at = lp.xyz / lp.w * 0.5 + 0.5;
    vec3 to_eye = eye - p;
    float distance = length(to_eye);
    vec3 v = to_eye / distance;
    float fog = smoothstep(fog_range.x, fog_range.y, distance);
    float clear = (1.0 - fog) * exposure;
    vec3 fogged = sky(-v) * (fog * exposure);
    vec3 diffuse, key, gloss;
#ifdef TWO_SIDED
    v_uv = in_uv;
    v_position = p;
    v_flat_normal = n;
    v_sliver = gl_VertexID >= first_cut_vertex ? 1 : 0;
    float shadow = key_visibility(shadow_at);
    // Thin cloth lets 12 % of the light on the other side through, as the full tier's.
    vec3 facing, away;
    point_lights(n, p, facing, away);
    side(n, p, v, true, front_is_winding, diffuse, key, gloss);
    v_light_a = (diffuse + facing + 0.12 * away + key * shadow) * clear;
    v_add_a = gloss * (shadow * clear) + fogged;
    side(-n, p, v, true, !front_is_winding, diffuse, key, gloss);
    v_light_b = (diffuse + away + 0.12 * facing + key * shadow) * clear;
    v_add_b = gloss * (shadow * clear) + fogged;
#else
    v_floor = p.xz;
    v_shadow = shadow_at;
    vec3 facing, away;
    point_lights(n, p, facing, away);
    side(n, p, v, false, false, diffuse, key, gloss);
    v_light_a = (diffuse + facing) * clear;
    v_add_a = fogged;
    // key and gloss are key_color times a scalar here: the fragment stage takes the scalars.
    float white = max(dot(key_color, vec3(1.0)), 1e-6);
    v_key_a = vec2(dot(key, vec3(1.0)), dot(gloss, vec3(1.0))) * (clear / white);
#endif
    gl_Position = depth_pushed(view_proj * world, p, pushed_by(p, n));
}
