#version 330 core
// Debug pass: shows one raw G-buffer channel (or the shadow map) mapped into visible colours.
uniform sampler2D g_position;
uniform sampler2D g_normal;
uniform sampler2D g_albedo;
uniform sampler2D g_depth;
uniform sampler2D shadow_depth;
// 1 position, 2 normal, 3 albedo, 4 material id, 5 depth, 6 shadow map
uniform int channel;
uniform float near;
uniform float far;

in vec2 v_uv;
out vec4 f_color;

void main() {
    vec4 a = texture(g_albedo, v_uv);
    bool covered = a.a > 0.0;
    vec3 c = vec3(0.0);
    if (channel == 1) {
        c = covered ? fract(texture(g_position, v_uv).xyz) : vec3(0.0);
    } else if (channel == 2) {
        c = covered ? texture(g_normal, v_uv).xyz * 0.5 + 0.5 : vec3(0.0);
    } else if (channel == 3) {
        c = a.rgb;
    } else if (channel == 4) {
        int m = int(a.a * 255.0 + 0.5);
        c = vec3(m & 1, (m >> 1) & 1, (m >> 2) & 1) * (m > 0 ? 0.9 : 0.0) + float(m > 0) * 0.1;
    } else if (channel == 5) {
        // Linearised so near geometry is not lost in the 0.99..1 band of window depth.
        float z = texture(g_depth, v_uv).r * 2.0 - 1.0;
        float lin = 2.0 * near * far / (far + near - z * (far - near));
        c = vec3(1.0 - clamp((lin - near) / 8.0, 0.0, 1.0));
    } else if (channel == 6) {
        c = vec3(texture(shadow_depth, v_uv).r);
    }
    f_color = vec4(c, 1.0);
}
