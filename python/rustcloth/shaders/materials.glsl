// Surface colours shared by the geometry pass and the software tier's forward pass: the
// cloth's procedural fabric and the floor's tiles, box-filtered by each pixel's footprint.
// The including shader declares the uniforms they read: cloth_size and base_color.

vec3 srgb_decode(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(0.04045, c));
}

// A hash without sin (Hoskins): llvmpipe evaluates sin as a long polynomial.
float hash(vec2 p) {
    vec3 p3 = fract(vec3(p.xyx) * 0.1031);
    p3 += dot(p3, p3.yzx + 33.33);
    return fract((p3.x + p3.y) * p3.z);
}

// Smooth value noise in [0, 1], faded to its mean once a cell is smaller than a pixel.
float fibre_noise(vec2 p) {
    vec2 i = floor(p), f = fract(p);
    vec2 u = f * f * (3.0 - 2.0 * f);
    float n = mix(mix(hash(i), hash(i + vec2(1, 0)), u.x),
                  mix(hash(i + vec2(0, 1)), hash(i + vec2(1, 1)), u.x), u.y);
    float fade = clamp(1.5 - 1.5 * max(fwidth(p.x), fwidth(p.y)), 0.0, 1.0);
    return mix(0.5, n, fade);
}

// The tartan's colour integrated from 0 to x (in repeats): its mean over an interval is a
// difference of two of these, so stripes are box-filtered over the pixel and never alias.
vec3 tartan_integral(float x) {
    const vec3 colors[TARTAN_STRIPES] = TARTAN_COLORS;
    const float starts[TARTAN_STRIPES] = TARTAN_STARTS;
    const float widths[TARTAN_STRIPES] = TARTAN_WIDTHS;
    float whole = floor(x), t = x - whole;
    vec3 part = vec3(0.0);
    for (int k = 0; k < TARTAN_STRIPES; ++k) {
        part += colors[k] * clamp(t - starts[k], 0.0, widths[k]);
    }
    return whole * TARTAN_MEAN + part;  // TARTAN_MEAN: the integral over one repeat
}

vec3 tartan(float x) {
    float w = max(fwidth(x), 1e-4);
    return (tartan_integral(x + 0.5 * w) - tartan_integral(x - 0.5 * w)) / w;
}

// A 2/2 twill: at each crossing the warp or the weft thread is on top, in diagonal steps.
// Returns (weight of the warp colour, thread shading); both fade to (0.5, 1) once a thread
// is narrower than a pixel, where only the mixed colour is visible.
vec2 twill(vec2 m) {
    vec2 t = m / THREAD_PITCH_M;
    float fade = clamp(1.0 - 1.2 * max(fwidth(t.x), fwidth(t.y)), 0.0, 1.0);
    ivec2 c = ivec2(floor(t));
    bool warp = ((c.x + c.y) & 3) < 2;
    vec2 f = fract(t) * 2.0 - 1.0;
    float across = warp ? f.x : f.y;
    float shade = 1.0 - 0.35 * across * across;
    return vec2(mix(0.5, warp ? 1.0 : 0.0, fade), mix(1.0, shade, fade));
}

vec3 fabric(vec2 uv, bool front) {
    vec2 m = uv * cloth_size;
    vec2 weave = twill(m);
    float heather = 0.92 + 0.16 * fibre_noise(m * 70.0);
    vec3 c;
    if (front) {
        vec2 r = m / TARTAN_REPEAT_M;
        c = mix(tartan(r.y), tartan(r.x), weave.x);
    } else {
        c = MAT_CLOTH_BACK_COLOR;
    }
    return c * weave.y * heather;
}

// Floor tiles of 0.5 m with thin grout lines, box-filtered by the pixel's footprint.
vec3 floor_color(vec2 xz) {
    vec2 t = xz * 2.0;
    vec2 w = max(fwidth(t), vec2(1e-4));
    vec2 d = abs(fract(t + 0.5) - 0.5);
    vec2 line = clamp((0.012 - d) / w + 0.5, 0.0, 1.0);
    float grout = max(line.x, line.y) * clamp(1.0 - 8.0 * max(w.x, w.y), 0.0, 1.0);
    float tone = 0.94 + 0.12 * hash(floor(t)) * clamp(1.0 - 2.0 * max(w.x, w.y), 0.0, 1.0);
    return base_color * tone * (1.0 - 0.45 * grout);
}
