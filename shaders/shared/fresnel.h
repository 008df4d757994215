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

REFRACT_SHADERS_END

#endif
