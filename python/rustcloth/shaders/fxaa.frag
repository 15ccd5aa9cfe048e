#version 330 core
// FXAA pass: cheap edge anti-aliasing of the tone-mapped image (the G-buffer has no MSAA),
// which it also scales up to the output when the 3D passes drew fewer pixels.
uniform sampler2D image;
uniform vec2 texel;       // of the image
uniform bool enabled;     // off: a plain (bilinear) copy
in vec2 v_uv;
out vec4 f_color;

float luma(vec3 c) { return dot(c, vec3(0.299, 0.587, 0.114)); }

void main() {
    vec3 m = texture(image, v_uv).rgb;
    if (!enabled) { f_color = vec4(m, 1.0); return; }
    vec3 nw = texture(image, v_uv + vec2(-1.0, -1.0) * texel).rgb;
    vec3 ne = texture(image, v_uv + vec2(1.0, -1.0) * texel).rgb;
    vec3 sw = texture(image, v_uv + vec2(-1.0, 1.0) * texel).rgb;
    vec3 se = texture(image, v_uv + vec2(1.0, 1.0) * texel).rgb;
    float lnw = luma(nw), lne = luma(ne), lsw = luma(sw), lse = luma(se), lm = luma(m);
    float lmin = min(lm, min(min(lnw, lne), min(lsw, lse)));
    float lmax = max(lm, max(max(lnw, lne), max(lsw, lse)));
    // Flat areas (most of the frame) keep their pixel: no more taps.
    if (lmax - lmin < max(0.0312, 0.125 * lmax)) { f_color = vec4(m, 1.0); return; }
    vec2 dir = vec2(-((lnw + lne) - (lsw + lse)), (lnw + lsw) - (lne + lse));
    float reduce = max((lnw + lne + lsw + lse) * 0.03125, 1.0 / 128.0);
    float rcp = 1.0 / (min(abs(dir.x), abs(dir.y)) + reduce);
    dir = clamp(dir * rcp, vec2(-8.0), vec2(8.0)) * texel;
    vec3 a = 0.5 * (texture(image, v_uv + dir * (1.0 / 3.0 - 0.5)).rgb
                  + texture(image, v_uv + dir * (2.0 / 3.0 - 0.5)).rgb);
    vec3 b = a * 0.5 + 0.25 * (texture(image, v_uv - dir * 0.5).rgb
                             + texture(image, v_uv + dir * 0.5).rgb);
    float lb = luma(b);
    f_color = vec4((lb < lmin || lb > lmax) ? a : b, 1.0);
}
