#version 330 core
// SSAO pass, at half the output resolution: ambient occlusion from the depth buffer, so
// folds and the contact between cloth, sphere and floor darken the ambient and fill light.
uniform sampler2D g_normal;
uniform sampler2D g_albedo;
uniform sampler2D g_depth;
uniform mat4 view_proj;
uniform mat4 inv_view_proj;
uniform vec3 eye;
uniform float radius;

in vec2 v_uv;
out float f_ao;

float hash(vec2 p) { return fract(sin(dot(p, vec2(12.9898, 78.233))) * 43758.5453); }

vec3 world_at(vec2 uv) {
    float depth = texture(g_depth, uv).r;
    vec4 w = inv_view_proj * vec4(uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

void main() {
    if (texture(g_albedo, v_uv).a == 0.0) { f_ao = 1.0; return; }
    vec3 p = world_at(v_uv);
    vec3 n = normalize(texture(g_normal, v_uv).xyz);
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
    f_ao = 1.0 - occluded / float(SSAO_SAMPLES);
}
