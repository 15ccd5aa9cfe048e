#version 330 core
// Debug pass: one raw G-buffer channel (or the shadow map) in visible colours instead of
// lighting. The legend the overlay draws says how to read each one.
uniform sampler2D g_normal;
uniform sampler2D g_albedo;
uniform sampler2D g_depth;
uniform sampler2D shadow_depth;
uniform mat4 inv_view_proj;
uniform int view;           // VIEW_*
uniform float depth_range;  // m from the eye that the depth view spans, white to black
uniform vec3 eye;
uniform vec2 viewport;      // pixels

in vec2 v_uv;
out vec4 f_color;

void main() {
    vec4 a = texture(g_albedo, v_uv);
    int m = int(a.a * 255.0 + 0.5);
    bool covered = m > 0;
    float depth = texture(g_depth, v_uv).r;
    vec4 w = inv_view_proj * vec4(v_uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    vec3 p = w.xyz / w.w;
    vec3 c = vec3(0.08);
    if (view == VIEW_POSITION) {
        // Continuous (a sine per metre), so depth-buffer noise cannot flip a pixel 0 <-> 1.
        if (covered) c = 0.5 + 0.5 * sin(6.2831853 * p);
    } else if (view == VIEW_NORMAL) {
        if (covered) c = texture(g_normal, v_uv).xyz * 0.5 + 0.5;
    } else if (view == VIEW_ALBEDO) {
        if (covered) c = a.rgb;  // the square root of linear albedo: close to sRGB
    } else if (view == VIEW_MATERIAL) {
        const vec3 colors[MAT_COUNT] = MAT_DEBUG_COLORS;
        c = colors[clamp(m, 0, MAT_COUNT - 1)];
    } else if (view == VIEW_DEPTH) {
        if (covered) c = vec3(1.0 - clamp(length(p - eye) / depth_range, 0.0, 1.0));
    } else if (view == VIEW_SHADOW_MAP) {
        // The square map, letterboxed: a square of the viewport, not stretched to its shape.
        float side = min(viewport.x, viewport.y);
        vec2 q = (gl_FragCoord.xy - 0.5 * (viewport - side)) / side;
        if (all(greaterThanEqual(q, vec2(0.0))) && all(lessThanEqual(q, vec2(1.0)))) {
            c = vec3(texture(shadow_depth, q).r);
        }
    }
    f_color = vec4(c, 1.0);
}
