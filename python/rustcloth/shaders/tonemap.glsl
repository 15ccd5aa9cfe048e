// The last steps of every lit pixel, shared by the lighting pass, the software tier's forward
// pass and its sky: the sky's colour by direction, tone mapping and the sRGB curve. The
// including shader declares the uniforms sky() reads: sky_zenith and sky_horizon.

// The sRGB transfer curve by three square roots (Ian Taylor's fit, within a quarter of an
// 8-bit step of the exact curve): a third of the cost of pow on llvmpipe.
vec3 srgb_encode(vec3 c) {
    vec3 s1 = sqrt(clamp(c, 0.0, 1.0));
    vec3 s2 = sqrt(s1);
    vec3 s3 = sqrt(s2);
    return clamp(0.585122381 * s1 + 0.783140355 * s2 - 0.368262736 * s3, 0.0, 1.0);
}

// Khronos PBR Neutral: identity below 0.76, a soft shoulder above, hue kept.
vec3 tonemap(vec3 c) {
    const float start = 0.8 - 0.04;
    const float desaturation = 0.15;
    float x = min(c.r, min(c.g, c.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    c -= offset;
    float peak = max(c.r, max(c.g, c.b));
    if (peak < start) return c;
    const float d = 1.0 - start;
    float new_peak = 1.0 - d * d / (peak + d - start);
    c *= new_peak / peak;
    float g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
    return mix(c, vec3(new_peak), g);
}

vec3 sky(vec3 dir) {
    float up = clamp(dir.y, 0.0, 1.0);
    return mix(sky_horizon, sky_zenith, sqrt(up));
}

// Interleaved gradient noise (Jimenez) at a pixel (gl_FragCoord.xy), +-0.5 of an 8-bit step:
// no banding, no sin.
float dither8(vec2 pixel) {
    return (fract(52.9829189 * fract(dot(pixel, vec2(0.06711056, 0.00583715))))
            - 0.5) / 255.0;
}
