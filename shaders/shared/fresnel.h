// Fresnel reflectance of a dielectric interface, shared by the shaders (fresnel.glsl) and the C++ side.
#ifndef REFRACT_SHADERS_FRESNEL_H
#define REFRACT_SHADERS_FRESNEL_H

#include "shared_types.h"

REFRACT_SHADERS_BEGIN

// Eye rays trace at most this many reflected paths per pixel (per channel under dispersion) besides the
// first one: the reflection off the front of the object and two internal reflections. At any boundary
// after that the ray goes on with all of its light on the stronger side (transmitted unless R > 1/2), so
// no light is lost: a slab at normal incidence then reflects R + T^2 R, 6e-5 short of 2R / (1 + R), and
// the rest goes through. Total internal reflection needs no path (the ray equation turns the ray).
#define FRESNEL_EYE_REFLECTIONS 3u
// A reflected path whose share of the pixel's light is below this in every channel is not marched: it
// takes the floor or sky straight along its direction from where it leaves the boundary, dimmed by the
// medium along that line (medium_depth). That drops what else the grid would do to it (fog it would
// gather, refraction on the way out, further reflections), so it errs by at most this share of the
// difference: 1% of a pixel's light. Only the second internal
// reflection is that faint through glass (T R^2, 0.15% at normal incidence; the front's R and the first
// internal T R are 4%); in the default scene's still that path cost 17% of the eye-ray steps and about a
// third of the viewing pass (a pixel's SIMD neighbours waited for its fourth march; docs/perf-log/2026-12-01-faint-reflections-and-b-spline-voxelizer.md).
#define FRESNEL_EYE_TRACED_SHARE 0.01f
// Interactive frames (run_options_for) take every reflected path straight: marched, they were a third of
// an interactive view's time (the target camera's 134 -> 88 ms on two cores), and a drag's frame is sized
// to its budget, so the time buys pixels. What a preview loses is the fog's glow in reflections and their
// refraction on the way out: a few percent of the glass's pixels, gone in the still at release
// (docs/perf-log/2026-12-05-previews-take-reflections-straight.md).
#define FRESNEL_PREVIEW_TRACED_SHARE 2.0f
// Reflected paths that are marched gather fog at this many times the view step: they carry a few percent
// of a pixel's light (4% at normal incidence off glass), so the step's error in them is that share of a
// step error already well under the photon noise, while tracing them was 45% of the viewing pass
// (docs/perf-log/2026-12-03-where-a-still-frame-goes.md). TransportParams::tone.z holds the step.
#define FRESNEL_REFLECTED_VIEW_STEP 2.0f

// The unpolarized reflectance (the mean of s and p) of light meeting an interface from index n1 into index
// n2 with sin_i the sine of its angle of incidence on the n1 side: 1 beyond the critical angle.
REFRACT_INLINE float fresnel_reflectance(float n1, float n2, float sin_i) {
    float sin_t = n1 * sin_i / n2;
    if (sin_t >= 1.0f) return 1.0f;
    float cos_i = sqrt(max(1.0f - sin_i * sin_i, 0.0f));
    float cos_t = sqrt(1.0f - sin_t * sin_t);
    float rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    float rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

// The unpolarized reflectance of a thin film of index n1 and thickness d between n0 (the incident side)
// and n2, at one wavelength lambda (d_over_lambda = d / lambda): the Airy sum of the film's multiple
// reflections, |r|^2 = (a^2 + b^2 + 2ab cos 2delta) / (1 + a^2 b^2 + 2ab cos 2delta) per polarization with
// a, b the two interfaces' real amplitude coefficients and delta = 2 pi n1 d cos(t1) / lambda. 1 where
// nothing propagates in n2; a film beyond its own critical angle (frustrated total reflection, which
// needs complex coefficients) is taken as absent.
REFRACT_INLINE float film_reflectance(float n0, float n1, float n2, float sin0, float d_over_lambda) {
    float s1 = n0 * sin0 / n1, s2 = n0 * sin0 / n2;
    if (s2 >= 1.0f) return 1.0f;
    if (s1 >= 1.0f) return fresnel_reflectance(n0, n2, sin0);
    float c0 = sqrt(max(1.0f - sin0 * sin0, 0.0f)), c1 = sqrt(1.0f - s1 * s1), c2 = sqrt(1.0f - s2 * s2);
    float rs01 = (n0 * c0 - n1 * c1) / (n0 * c0 + n1 * c1), rs12 = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2);
    float rp01 = (n1 * c0 - n0 * c1) / (n1 * c0 + n0 * c1), rp12 = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    float cos_2delta = cos(12.5663706f * n1 * c1 * d_over_lambda);
    float s_cross = 2.0f * rs01 * rs12 * cos_2delta, p_cross = 2.0f * rp01 * rp12 * cos_2delta;
    float rs = (rs01 * rs01 + rs12 * rs12 + s_cross) / (1.0f + rs01 * rs01 * rs12 * rs12 + s_cross);
    float rp = (rp01 * rp01 + rp12 * rp12 + p_cross) / (1.0f + rp01 * rp01 * rp12 * rp12 + p_cross);
    return 0.5f * (rs + rp);
}

// A colour channel is a band of wavelengths, not one: the visible range split at 490 and 580 nm into
// blue (400-490), green (490-580) and red (580-700), each weighted evenly (a box sensitivity; colour-
// matching curves would shift hues a little) and sampled at FILM_BAND_SAMPLES midpoints, enough to
// follow a 1000 nm film's fringes (a period of ~45 nm of wavelength across the blue band).
#define FILM_BAND_SAMPLES 8

// The film's reflectance averaged over each channel's band, for thickness d_nm (nm).
REFRACT_INLINE vec3 film_band_reflectance(float n0, float n1, float n2, float sin0, float d_nm) {
    vec3 hi = vec3(700.0f, 580.0f, 490.0f), lo = vec3(580.0f, 490.0f, 400.0f);
    vec3 sum = vec3(0.0f);
    for (int k = 0; k < FILM_BAND_SAMPLES; ++k) {
        vec3 lambda = lo + (hi - lo) * ((float(k) + 0.5f) / float(FILM_BAND_SAMPLES));
        sum += vec3(film_reflectance(n0, n1, n2, sin0, d_nm / lambda.x), film_reflectance(n0, n1, n2, sin0, d_nm / lambda.y),
                    film_reflectance(n0, n1, n2, sin0, d_nm / lambda.z));
    }
    return sum * (1.0f / float(FILM_BAND_SAMPLES));
}

REFRACT_SHADERS_END

#endif
