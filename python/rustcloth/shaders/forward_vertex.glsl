// Software tier, forward pass, vertex stage (forward.vert: every surface but the cloth;
// forward_cloth.vert: the cloth, TWO_SIDED): all the lighting is computed per vertex and interpolated
// (Gouraud), so a pixel pays only for its surface colour, its shadow-map tap and the tone
// mapping. The meshes are fine enough for this: the cloth's particle grid, a sphere of 2,048
// quads, and a floor cut into a grid that is fine near the scene and coarse far away. Each
// side of a surface gets its own terms (thin cloth shows whichever faces the viewer); the
// shadow-map coordinates are exact to interpolate, as the key light's projection is
// orthographic.
uniform mat4 view_proj;
uniform mat4 model;
uniform mat4 light_view_proj;
uniform int material;
uniform bool front_is_winding;  // the cloth's front side is the triangles' front face
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

in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;

out vec3 v_world;
out vec3 v_shadow;  // shadow-map coordinates in [0, 1] (x, y, depth)
// For the side the normal faces (a) and, for the cloth, the other (b): light times the
// albedo, unshadowed (ambient and point lights), and the key light's, shadowed: times the
// albedo, and added.
out vec3 v_diffuse_a;
out vec3 v_key_a;
out vec3 v_gloss_a;
#ifdef TWO_SIDED
out vec2 v_uv;
out vec3 v_diffuse_b;
out vec3 v_key_b;
out vec3 v_gloss_b;
#endif
out vec4 v_fog;     // rgb: the sky behind; a: how much of it

#include "tonemap.glsl"

// What the side with normal n shows: (diffuse, key, gloss) as above.
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
    for (int i = 0; i < num_points; ++i) {
        vec3 d = point_pos[i] - p;
        float dist2 = dot(d, d);
        float r2 = point_reach[i] * point_reach[i];
        float window = max(1.0 - (dist2 / r2) * (dist2 / r2), 0.0);
        float pn_l = dot(n, d) * inversesqrt(dist2);
        float lit = pn_l > 0.0 ? pn_l : (cloth ? -0.12 * pn_l : 0.0);
        diffuse += point_color[i] * (lit * window * window / (dist2 + 0.01));
    }
}

void main() {
    vec4 world = model * vec4(in_position, 1.0);
    vec3 p = world.xyz;
    v_world = p;
    vec3 n = normalize(mat3(model) * in_normal);  // rotation, translation, uniform scale
    vec3 l = -key_dir;
    // Looked up from just off the surface on the light's side, as the lighting pass does.
    vec4 lp = light_view_proj * vec4(p + n * (dot(n, l) >= 0.0 ? 0.01 : -0.01), 1.0);
    v_shadow = lp.xyz / lp.w * 0.5 + 0.5;
    vec3 to_eye = eye - p;
    float distance = length(to_eye);
    vec3 v = to_eye / distance;
#ifdef TWO_SIDED
    v_uv = in_uv;
    side(n, p, v, true, front_is_winding, v_diffuse_a, v_key_a, v_gloss_a);
    side(-n, p, v, true, !front_is_winding, v_diffuse_b, v_key_b, v_gloss_b);
#else
    side(n, p, v, false, false, v_diffuse_a, v_key_a, v_gloss_a);
#endif
    v_fog = vec4(sky(-v), smoothstep(fog_range.x, fog_range.y, distance));
    gl_Position = view_proj * world;
}
