#version 330 core
// Fill pass, at half the output resolution: the point lights' diffuse light (rgb) and, when
// SSAO is on, ambient occlusion (a). Both vary slowly across the image, so a quarter of the
// pixels is enough; the lighting pass upsamples them with one bilinear tap. (On llvmpipe
// every light costs every pixel it is evaluated at: here it costs a quarter as much.)
uniform sampler2D g_normal;
uniform sampler2D g_albedo;
uniform sampler2D g_depth;
uniform mat4 view_proj;
uniform mat4 inv_view_proj;
uniform vec3 eye;
uniform float radius;       // m, the SSAO kernel's
uniform bool ao_enabled;
uniform int num_points;
uniform vec3 point_pos[MAX_POINT_LIGHTS];
uniform vec3 point_color[MAX_POINT_LIGHTS];  // linear, times the intensity
uniform float point_reach[MAX_POINT_LIGHTS];

in vec2 v_uv;
out vec4 f_fill;

// Interleaved gradient noise (Jimenez): a per-pixel angle without sin.
float hash(vec2 p) { return fract(52.9829189 * fract(dot(p, vec2(0.06711056, 0.00583715)))); }

vec3 world_at(vec2 uv) {
    float depth = texture(g_depth, uv).r;
    vec4 w = inv_view_proj * vec4(uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

float occlusion(vec3 p, vec3 n) {
    // A per-pixel random rotation of the kernel trades banding for fine noise.
    float angle = 6.2831853 * hash(gl_FragCoord.xy);
    vec3 helper = abs(n.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 t = normalize(cross(helper, n));
    vec3 b = cross(n, t);
    vec3 tr = cos(angle) * t + sin(angle) * b;
    vec3 br = cross(n, tr);
    float dist_p = length(eye - p);
    float occluded = 0.0;
    for (int i = 0; i < SSAO_SAMPLES; ++i) {
        float fi = float(i) + 0.5;
        // Fibonacci hemisphere, denser near the centre.
        float z = 1.0 - fi / float(SSAO_SAMPLES);
        float r = sqrt(1.0 - z * z);
        float a = fi * 2.3999632;
        float scale = mix(0.2, 1.0, (fi / float(SSAO_SAMPLES)) * (fi / float(SSAO_SAMPLES)));
        vec3 s = p + (tr * (r * cos(a)) + br * (r * sin(a)) + n * z) * radius * scale;
        vec4 clip = view_proj * vec4(s, 1.0);
        vec2 uv = clip.xy / clip.w * 0.5 + 0.5;
        if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) continue;
        if (texture(g_albedo, uv).a == 0.0) continue;
        float dist_stored = length(eye - world_at(uv));
        float range = smoothstep(0.0, 1.0, radius / max(abs(dist_p - dist_stored), 1e-4));
        occluded += (dist_stored < length(eye - s) - 0.01 * radius ? 1.0 : 0.0) * range;
    }
    return 1.0 - occluded / float(SSAO_SAMPLES);
}

void main() {
    int mat = int(texture(g_albedo, v_uv).a * 255.0 + 0.5);
    if (mat == 0 || mat == MAT_MARKER || mat == MAT_LIGHT) { f_fill = vec4(0.0, 0.0, 0.0, 1.0); return; }
    vec3 p = world_at(v_uv);
    vec3 n = normalize(texture(g_normal, v_uv).xyz);
    bool cloth = mat == MAT_CLOTH_FRONT || mat == MAT_CLOTH_BACK;
    vec3 light = vec3(0.0);
    for (int i = 0; i < num_points; ++i) {
        vec3 d = point_pos[i] - p;
        float dist2 = dot(d, d);
        float r2 = point_reach[i] * point_reach[i];
        float window = max(1.0 - (dist2 / r2) * (dist2 / r2), 0.0);
        float n_l = dot(n, d) * inversesqrt(dist2);
        // Thin cloth lets a little of a light behind it through.
        float lit = n_l > 0.0 ? n_l : (cloth ? -0.12 * n_l : 0.0);
        light += point_color[i] * (lit * window * window / (dist2 + 0.01));
    }
    f_fill = vec4(light, ao_enabled ? occlusion(p, n) : 1.0);
}
