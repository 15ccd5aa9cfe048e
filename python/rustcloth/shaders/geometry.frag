#version 330 core
// Geometry pass: writes world position, unit normal and albedo + material id so lighting
// and the debug views work per pixel without touching the meshes again.
const int MAT_CLOTH_FRONT = 1;
const int MAT_CLOTH_BACK = 2;
const int MAT_FLOOR = 3;
const int MAT_SPHERE = 4;
const int MAT_MARKER = 5;

uniform int material;
uniform vec3 base_color;
uniform vec3 back_color;
// 0: woven texture; 1: cloth coloured by in_scalar (strain, speed or pinned views).
uniform int cloth_mode;
uniform float scalar_scale;
uniform vec2 grid_size;

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in float v_scalar;

layout(location = 0) out vec4 g_position;
layout(location = 1) out vec4 g_normal;
layout(location = 2) out vec4 g_albedo;

vec3 heat(float t) {
    t = clamp(t, 0.0, 1.0);
    return clamp(vec3(1.5 * t, 1.5 - abs(2.0 * t - 1.0) * 1.5, 1.5 * (1.0 - t)), 0.0, 1.0);
}

// A plain weave: warp and weft threads alternate over/under, with a coarse coloured check.
vec3 woven(vec2 uv, vec3 a, vec3 b) {
    vec2 cell = uv * grid_size;
    vec2 f = fract(cell * 2.0);
    ivec2 c = ivec2(floor(cell * 2.0));
    bool warp_on_top = ((c.x + c.y) & 1) == 0;
    float thread = warp_on_top ? 1.0 - 0.6 * pow(abs(f.x - 0.5) * 2.0, 3.0)
                               : 1.0 - 0.6 * pow(abs(f.y - 0.5) * 2.0, 3.0);
    ivec2 check = ivec2(floor(uv * 8.0));
    bool stripe = ((check.x + check.y) & 1) == 0;
    return (stripe ? a : b) * (0.75 + 0.25 * thread);
}

void main() {
    vec3 n = normalize(v_normal);
    int mat = material;
    vec3 albedo = base_color;
    if (mat == MAT_CLOTH_FRONT) {
        // Two-sided cloth: the back face shades with the flipped normal and its own colour.
        if (!gl_FrontFacing) {
            n = -n;
            mat = MAT_CLOTH_BACK;
            albedo = woven(v_uv, back_color, back_color * vec3(0.55, 0.65, 1.1));
        } else {
            albedo = woven(v_uv, base_color, base_color * 0.85);
        }
        if (cloth_mode == 1) {
            albedo = heat(v_scalar * scalar_scale);
        }
    } else if (mat == MAT_FLOOR) {
        ivec2 c = ivec2(floor(v_world.xz * 2.0));
        albedo = base_color * (((c.x + c.y) & 1) == 0 ? 1.0 : 0.8);
    }
    g_position = vec4(v_world, 1.0);
    g_normal = vec4(n, 0.0);
    g_albedo = vec4(albedo, float(mat) / 255.0);
}
