#version 330 core
// Lighting pass: shades every covered pixel once from the G-buffer: a directional key light
// with a PCF-filtered shadow map, NUM_POINT point lights (Blinn-Phong) and ambient.
#define NUM_POINT 8
const int MAT_MARKER = 5;

uniform sampler2D g_position;
uniform sampler2D g_normal;
uniform sampler2D g_albedo;
uniform sampler2DShadow shadow_map;
uniform sampler2D ao_map;
uniform bool ao_enabled;

uniform mat4 light_view_proj;
uniform vec3 light_dir;      // direction the light travels, unit
uniform vec3 light_color;
uniform bool shadows_enabled;
uniform float shadow_texel;
uniform vec3 eye;
uniform vec3 ambient;
uniform vec3 point_pos[NUM_POINT];
uniform vec3 point_color[NUM_POINT];
uniform float point_radius;
uniform vec3 sky_top;
uniform vec3 sky_bottom;

in vec2 v_uv;
out vec4 f_color;

float shadow_factor(vec3 p, vec3 n) {
    if (!shadows_enabled) return 1.0;
    // Normal offset keeps lit surfaces from shadowing themselves (acne) on the grazing cloth.
    vec4 lp = light_view_proj * vec4(p + n * 0.01, 1.0);
    vec3 s = lp.xyz / lp.w * 0.5 + 0.5;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    float bias = 0.0015;
    float lit = 0.0;
    // 3x3 percentage-closer filter over hardware-filtered 2x2 compares: soft, stable edges
    // at a third of the cost of a 5x5 kernel (llvmpipe is fill-rate bound).
    for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x)
            lit += texture(shadow_map, vec3(s.xy + vec2(x, y) * 1.5 * shadow_texel, s.z - bias));
    return lit / 9.0;
}

vec3 tonemap(vec3 c) {
    // ACES fit (Narkowicz): keeps highlights from clipping to flat white.
    c *= 0.8;
    return clamp((c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14), 0.0, 1.0);
}

void main() {
    vec4 albedo_mat = texture(g_albedo, v_uv);
    int mat = int(albedo_mat.a * 255.0 + 0.5);
    if (mat == 0) {
        f_color = vec4(mix(sky_bottom, sky_top, v_uv.y), 1.0);
        return;
    }
    vec3 albedo = albedo_mat.rgb;
    if (mat == MAT_MARKER) {
        f_color = vec4(albedo, 1.0);
        return;
    }
    vec3 p = texture(g_position, v_uv).xyz;
    vec3 n = normalize(texture(g_normal, v_uv).xyz);
    vec3 v = normalize(eye - p);
    float shininess = mat <= 2 ? 16.0 : 48.0;
    float spec_strength = mat <= 2 ? 0.08 : 0.25;

    vec3 l = -light_dir;
    vec3 h = normalize(l + v);
    float ndl = max(dot(n, l), 0.0);
    float ao = 1.0;
    if (ao_enabled) {
        // 2x2 box filter of the noisy SSAO term, free with one bilinear tap between texels.
        ao = texture(ao_map, v_uv + 0.5 / vec2(textureSize(ao_map, 0))).r;
    }
    vec3 color = ambient * albedo * ao;
    color += shadow_factor(p, n) * light_color
             * (albedo * ndl + spec_strength * pow(max(dot(n, h), 0.0), shininess) * float(ndl > 0.0));

    for (int i = 0; i < NUM_POINT; ++i) {
        vec3 d = point_pos[i] - p;
        float dist = length(d);
        vec3 pl = d / dist;
        float att = clamp(1.0 - dist / point_radius, 0.0, 1.0);
        att *= att;
        float pndl = max(dot(n, pl), 0.0);
        vec3 ph = normalize(pl + v);
        // Fill lights get a softer lobe than the key so they read as rims, not hot spots.
        color += point_color[i] * att * mix(1.0, ao, 0.6) * (albedo * pndl
                 + 0.5 * spec_strength * pow(max(dot(n, ph), 0.0), 0.5 * shininess) * float(pndl > 0.0));
    }
    f_color = vec4(pow(tonemap(color), vec3(1.0 / 2.2)), 1.0);
}
