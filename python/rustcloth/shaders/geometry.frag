#version 330 core
// Geometry pass: writes each surface's unit normal (facing the viewer; in alpha, how far its
// depth was pushed back, see depth_push.glsl) and its albedo (stored as its square root,
// gamma 2, for precision in the darks at the cost of one sqrt) with the material id in
// alpha; the depth buffer gives the position. The
// cloth's fabric is procedural, in metres of cloth, so its scale has nothing to do with the
// particle grid. MAT_*, VIEW_* and the colours come from the generated header.

uniform int material;
uniform vec3 base_color;   // linear; static meshes and markers
uniform bool front_is_winding;  // the cloth's front side is the triangles' front face
uniform vec2 cloth_size;   // m along i and j: uv * cloth_size is a point of the cloth in m
uniform vec2 grid_cells;   // nx - 1, ny - 1: the particle grid, drawn in the scalar views
uniform int view;          // VIEW_*: the strain, speed and pinned views colour the cloth
uniform vec3 eye;

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in float v_scalar;

in float v_push;
flat in int v_sliver;
layout(location = 0) out vec4 g_normal;
layout(location = 1) out vec4 g_albedo;

#include "materials.glsl"

vec3 colormap(float t) {
    const vec3 stops[COLORMAP_STOPS] = COLORMAP;
    float s = clamp(t, 0.0, 1.0) * float(COLORMAP_STOPS - 1);
    int k = min(int(s), COLORMAP_STOPS - 2);
    return mix(stops[k], stops[k + 1], s - float(k));
}

// The scalar views' cloth colour (sRGB), with the particle grid's rows and columns drawn
// faintly so the sheet's structure shows even where the value is the same everywhere.
vec3 scalar_color(vec2 uv, float value) {
    vec3 c;
    if (view == VIEW_STRAIN) {
        c = colormap(value / STRAIN_MAX);
    } else if (view == VIEW_SPEED) {
        c = colormap(log(max(value, SPEED_MIN) / SPEED_MIN) / log(SPEED_MAX / SPEED_MIN));
    } else {
        c = value > 1.5 ? PIN_GRABBED_COLOR : value > 0.5 ? PIN_PINNED_COLOR : PIN_FREE_COLOR;
    }
    vec2 g = uv * grid_cells;
    vec2 w = max(fwidth(g), vec2(1e-4));
    vec2 d = abs(fract(g + 0.5) - 0.5) / w;
    // Lines fade out where cells get narrower than 5 pixels, or they would be all you see.
    float line = (1.0 - clamp(min(d.x, d.y) - 0.5, 0.0, 1.0))
               * clamp(1.0 / (5.0 * max(w.x, w.y)) * 2.0 - 1.0, 0.0, 1.0);
    // Lines lighter than a dark colour, darker than a light one: visible on either.
    vec3 ink = dot(c, vec3(0.299, 0.587, 0.114)) < 0.4 ? mix(c, vec3(1.0), 0.5) : c * 0.5;
    return mix(c, ink, line * 0.7);
}

void main() {
    vec3 n = normalize(v_normal);
    int mat = material;
    vec3 albedo = base_color;  // linear
    if (mat == MAT_CLOTH_FRONT) {
        // Two-sided cloth: the side facing the viewer shades with the normal facing it. Which
        // side that is the winding says, unless the triangle winds against its own vertex
        // normals: then the normals say, so that it shades as the cloth round it. The face's
        // normal from the position's derivatives points to the viewer; on a triangle that
        // agrees with its normals this is the winding's choice, bit for bit. A sliver along a
        // cut whose cut vertices crossed stands at any angle to the cloth round it, so that
        // some of its normals can be on either side of its face (which split it into the two
        // sides, a lining-coloured speck in the fabric): there the side the normal faces
        // toward the eye is seen.
        vec3 to_viewer = cross(dFdx(v_world), dFdy(v_world));
        bool against = dot(n, gl_FrontFacing ? to_viewer : -to_viewer) < 0.0;
        bool seen = v_sliver != 0 ? dot(n, eye - v_world) >= 0.0  // the normal's side is seen
                                  : gl_FrontFacing != against;
        if (!seen) n = -n;
        bool front = seen == front_is_winding;
        mat = front ? MAT_CLOTH_FRONT : MAT_CLOTH_BACK;
        if (view == VIEW_STRAIN || view == VIEW_SPEED || view == VIEW_PINNED) {
            albedo = srgb_decode(scalar_color(v_uv, v_scalar));
        } else {
            albedo = fabric(v_uv, front);
        }
    } else if (mat == MAT_FLOOR) {
        albedo = floor_color(v_world.xz);
    }
    g_normal = vec4(n, v_push);  // how far to bring the position back (depth_push.glsl)
    g_albedo = vec4(sqrt(clamp(albedo, 0.0, 1.0)), float(mat) / 255.0);
}
