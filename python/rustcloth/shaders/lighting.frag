#version 330 core
// Lighting pass: shades every pixel once from the G-buffer, in linear light. The key light
// is shadow-mapped; the point lights' diffuse light and SSAO come from the half-size fill
// pass; a sky and ground ambient is darkened by the AO. Under the key light cloth is a
// Lambert base beneath the Charlie sheen lobe (KHR_materials_sheen), floor, sphere and
// colliders are GGX, and the sphere also mirrors the point lights; distant surfaces fog into the sky. Then:
// exposure, Khronos PBR Neutral tone mapping, the sRGB curve and a dither against banding.
// The scalar debug views keep their colour map: lit by the key alone, not tone-mapped.

uniform sampler2D g_normal;
uniform sampler2D g_albedo;
uniform sampler2D g_depth;
uniform sampler2DShadow shadow_map;
uniform sampler2D fill_map;  // rgb: point lights' irradiance; a: ambient occlusion

uniform mat4 inv_view_proj;
uniform mat4 light_view_proj;
uniform vec3 eye;
uniform vec3 key_dir;       // direction the key light travels, unit
uniform vec3 key_color;     // linear, times its intensity
uniform bool shadows_enabled;
uniform float shadow_texel;
uniform vec3 sky_zenith;    // linear
uniform vec3 sky_horizon;
uniform vec3 ground_color;
uniform float ambient;
uniform int num_points;     // for the sphere's highlights of them
uniform vec3 point_pos[MAX_POINT_LIGHTS];
uniform vec3 point_color[MAX_POINT_LIGHTS];  // linear, times the intensity
uniform float point_reach[MAX_POINT_LIGHTS];
uniform vec2 fog_range;     // m from the eye where fog starts and where it is complete
uniform float exposure;
uniform bool scalar_view;

in vec2 v_uv;
out vec4 f_color;

const float PI = 3.14159265;

#include "tonemap.glsl"

// -- BRDFs ----------------------------------------------------------------------------------
// Charlie sheen distribution (Estevez and Kulla 2017), alpha = roughness^2.
float d_charlie(float alpha, float n_h) {
    float inv = 1.0 / alpha;
    float sin2 = max(1.0 - n_h * n_h, 1e-4);
    return (2.0 + inv) * pow(sin2, 0.5 * inv) / (2.0 * PI);
}

float charlie_l(float x, float alpha) {
    float t = (1.0 - alpha) * (1.0 - alpha);
    float a = mix(21.5473, 25.3245, t), b = mix(3.82987, 3.32435, t);
    float c = mix(0.19823, 0.16801, t), d = mix(-1.97760, -1.27393, t);
    float e = mix(-4.32054, -4.85967, t);
    return a / (1.0 + b * pow(x, c)) + d * x + e;
}

float charlie_lambda(float cos_theta, float alpha) {
    return cos_theta < 0.5 ? exp(charlie_l(cos_theta, alpha))
                           : exp(2.0 * charlie_l(0.5, alpha) - charlie_l(1.0 - cos_theta, alpha));
}

// The sheen visibility of Estevez and Kulla, as KHR_materials_sheen describes it.
float v_sheen(float alpha, float n_l, float n_v) {
    float lambda = charlie_lambda(n_v, alpha) + charlie_lambda(n_l, alpha);
    return clamp(1.0 / ((1.0 + lambda) * 4.0 * n_v * n_l), 0.0, 1.0);
}

// Directional albedo of the sheen lobe (Estevez and Kulla's fit): what the base loses to it.
float sheen_albedo(float n_v, float alpha) {
    float c = 1.0 - n_v;
    return 0.65584461 * c * c * c + 1.0 / (4.16526551 + exp(-7.97291361 * sqrt(alpha) + 6.33516894));
}

float d_ggx(float alpha, float n_h) {
    float a2 = alpha * alpha;
    float f = n_h * n_h * (a2 - 1.0) + 1.0;
    return a2 / (PI * f * f);
}

float v_ggx(float alpha, float n_l, float n_v) {
    float a2 = alpha * alpha;
    float gv = n_l * sqrt(n_v * n_v * (1.0 - a2) + a2);
    float gl = n_v * sqrt(n_l * n_l * (1.0 - a2) + a2);
    return 0.5 / max(gv + gl, 1e-5);
}

float fresnel(float f0, float v_h) {
    float x = 1.0 - v_h, x2 = x * x;
    return f0 + (1.0 - f0) * x2 * x2 * x;
}

struct Surface {
    int mat;
    vec3 albedo;
    vec3 sheen;
    float alpha;    // roughness^2
    float base;     // weight of the diffuse base under the sheen
};

// Outgoing radiance towards v from the key light arriving along l with irradiance e (at
// normal incidence). Thin cloth also lets a little light through from its far side.
vec3 shade(Surface s, vec3 n, vec3 v, vec3 l, vec3 e) {
    float n_l = dot(n, l);
    if (s.mat == MAT_CLOTH_FRONT || s.mat == MAT_CLOTH_BACK) {
        if (n_l <= 0.0) return s.albedo * e * (0.12 * -n_l);
        float n_v = max(dot(n, v), 1e-3);
        float n_h = max(dot(n, normalize(l + v)), 0.0);
        vec3 sheen = s.sheen * d_charlie(s.alpha, n_h) * v_sheen(s.alpha, n_l, n_v);
        return (s.albedo * s.base + PI * sheen) * e * n_l;
    }
    if (n_l <= 0.0) return vec3(0.0);
    vec3 h = normalize(l + v);
    float n_v = max(dot(n, v), 1e-3);
    float f = fresnel(0.04, max(dot(v, h), 0.0));
    float spec = d_ggx(s.alpha, max(dot(n, h), 0.0)) * v_ggx(s.alpha, n_l, n_v) * f;
    return (s.albedo * (1.0 - f) + PI * spec) * e * n_l;
}

// A point light's highlight on a glossy surface (normalised Blinn-Phong: cheap enough to
// pay per light, and paid only where the sphere is).
vec3 highlight(Surface s, vec3 n, vec3 v, vec3 l, vec3 e) {
    float n_l = dot(n, l);
    if (n_l <= 0.0) return vec3(0.0);
    float power = 2.0 / (s.alpha * s.alpha) - 2.0;
    float n_h = max(dot(n, normalize(l + v)), 0.0);
    return vec3(0.04 * (power + 8.0) / 8.0 * pow(n_h, power)) * e * n_l;
}

float shadow_factor(vec3 p, vec3 n, vec3 l) {
    if (!shadows_enabled) return 1.0;
    // Look up from just off the surface on the light's side, so a surface does not shadow
    // itself (acne) and thin cloth lit from behind is not shadowed by its own front.
    vec3 offset = n * (dot(n, l) >= 0.0 ? 0.01 : -0.01);
    vec4 lp = light_view_proj * vec4(p + offset, 1.0);
    vec3 s = lp.xyz / lp.w * 0.5 + 0.5;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    // Two hardware-filtered (2x2) compares half a texel apart diagonally: a soft edge for
    // the price of two taps (each costs every lit pixel on llvmpipe).
    vec2 o = vec2(0.75, -0.75) * shadow_texel;
    return 0.5 * (texture(shadow_map, vec3(s.xy + o, s.z - 0.0015))
                  + texture(shadow_map, vec3(s.xy - o, s.z - 0.0015)));
}

// Karis's fit of the split-sum environment BRDF: how much of the sky a GGX surface mirrors.
vec3 sky_reflection(vec3 n, vec3 v, float roughness) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
    const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    vec4 r = roughness * c0 + c1;
    float n_v = max(dot(n, v), 1e-3);
    float a004 = min(r.x * r.x, exp2(-9.28 * n_v)) * r.x + r.y;
    vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
    vec3 dir = reflect(-v, n);
    dir.y = abs(dir.y);  // what a rough reflection below the horizon picks up: more sky
    return sky(normalize(mix(dir, n, roughness * roughness))) * (0.04 * ab.x + ab.y);
}

void main() {
    float depth = texture(g_depth, v_uv).r;
    vec4 world = inv_view_proj * vec4(v_uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    vec3 p = world.xyz / world.w;
    vec3 view_dir = normalize(p - eye);
    vec4 albedo_mat = texture(g_albedo, v_uv);
    int mat = int(albedo_mat.a * 255.0 + 0.5);
    p -= view_dir * texture(g_normal, v_uv).a;  // a solid's depth was pushed (depth_push.glsl)
    vec3 color;
    float dither = dither8(gl_FragCoord.xy);
    if (mat == 0) {
        f_color = vec4(srgb_encode(tonemap(sky(view_dir) * exposure)) + dither, 1.0);
        return;
    }
    float distance = length(p - eye);
    if (distance >= fog_range.y && !scalar_view) {  // all fog: nothing else to compute
        f_color = vec4(srgb_encode(tonemap(sky(view_dir) * exposure)) + dither, 1.0);
        return;
    }
    vec3 n = normalize(texture(g_normal, v_uv).xyz);
    vec3 l = -key_dir;
    float shadow = shadow_factor(p, n, l);
    vec3 albedo = albedo_mat.rgb * albedo_mat.rgb;  // stored as its square root
    if (scalar_view && (mat == MAT_CLOTH_FRONT || mat == MAT_CLOTH_BACK)) {
        float lit = 0.45 + 0.55 * max(dot(n, l), 0.0) * shadow;
        f_color = vec4(srgb_encode(albedo) * lit, 1.0);
        return;
    }
    if (mat == MAT_MARKER || mat == MAT_LIGHT) {
        float strength = mat == MAT_MARKER ? MAT_MARKER_EMISSIVE : MAT_LIGHT_EMISSIVE;
        f_color = vec4(srgb_encode(tonemap(albedo * strength)) + dither, 1.0);
        return;
    }
    vec3 v = -view_dir;
    Surface s;
    s.mat = mat;
    s.albedo = albedo;
    s.sheen = vec3(0.0);
    s.base = 1.0;
    float roughness = mat == MAT_FLOOR ? MAT_FLOOR_ROUGHNESS
                    : mat == MAT_COLLIDER ? MAT_COLLIDER_ROUGHNESS : MAT_SPHERE_ROUGHNESS;
    if (mat == MAT_CLOTH_FRONT || mat == MAT_CLOTH_BACK) {
        bool front = mat == MAT_CLOTH_FRONT;
        roughness = front ? MAT_CLOTH_FRONT_ROUGHNESS : MAT_CLOTH_BACK_ROUGHNESS;
        s.sheen = front ? MAT_CLOTH_FRONT_SHEEN : MAT_CLOTH_BACK_SHEEN;
    }
    s.alpha = max(roughness * roughness, 0.01);
    if (mat == MAT_CLOTH_FRONT || mat == MAT_CLOTH_BACK) {
        float peak = max(s.sheen.r, max(s.sheen.g, s.sheen.b));
        s.base = 1.0 - peak * sheen_albedo(max(dot(n, v), 1e-3), s.alpha);
    }

    vec4 fill = texture(fill_map, v_uv);
    float ao = fill.a;
    vec3 hemi = mix(ground_color, 0.5 * (sky_zenith + sky_horizon), 0.5 + 0.5 * n.y);
    color = ambient * hemi * albedo * s.base * ao;
    color += albedo * s.base * fill.rgb * mix(1.0, ao, 0.5);
    if (mat == MAT_FLOOR || mat == MAT_SPHERE || mat == MAT_COLLIDER) {
        color += ambient * sky_reflection(n, v, roughness) * ao;
    }
    color += shadow * shade(s, n, v, l, key_color);
    if (mat == MAT_SPHERE) {
        for (int i = 0; i < num_points; ++i) {
            vec3 d = point_pos[i] - p;
            float dist2 = dot(d, d);
            float r2 = point_reach[i] * point_reach[i];
            float window = max(1.0 - (dist2 / r2) * (dist2 / r2), 0.0);
            vec3 e = point_color[i] * (window * window / (dist2 + 0.01));
            color += highlight(s, n, v, d * inversesqrt(dist2), e);
        }
    }

    float fog = smoothstep(fog_range.x, fog_range.y, distance);
    color = mix(color, sky(view_dir), fog);
    f_color = vec4(srgb_encode(tonemap(color * exposure)) + dither, 1.0);
}
