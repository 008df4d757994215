// What a pixel's linear radiance becomes on screen, shared by the viewing pass and the pixels
// view_refine.comp interpolates, so both give a pixel the same bytes.

// Narkowicz's fit of the ACES filmic curve, then the sRGB transfer function.
vec3 tone_map(vec3 x) {
    x = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    return mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, greaterThan(x, vec3(0.0031308)));
}

// Linear radiance times the exposure multiplier -> opaque RGBA8, red in the low byte.
uint srgb8(vec3 radiance, float exposure) {
    uvec3 bytes = uvec3(clamp(tone_map(radiance * exposure), 0.0, 1.0) * 255.0 + 0.5);
    return bytes.r | (bytes.g << 8u) | (bytes.b << 16u) | (255u << 24u);
}
