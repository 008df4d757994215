// Phase functions of the viewing pass and of photon random walks, shared with the C++ tests that
// integrate them over the sphere and histogram their samples. cos_theta is the cosine between the
// light's travel direction and the scattered direction (towards the eye), so positive g (or Schlick k)
// favours forward scattering.
#ifndef REFRACT_SHADERS_PHASE_H
#define REFRACT_SHADERS_PHASE_H

#include "shared_types.h"

REFRACT_SHADERS_BEGIN

#define PHASE_ISOTROPIC_ID 0u
#define PHASE_SCHLICK_ID 1u
#define PHASE_HG_ID 2u

const float kInvFourPi = 0.0795774715f;

REFRACT_INLINE float phase_isotropic() { return kInvFourPi; }

REFRACT_INLINE float phase_schlick(float cos_theta, float k) {
    float d = 1.0f - k * cos_theta;
    return kInvFourPi * (1.0f - k * k) / (d * d);
}

REFRACT_INLINE float phase_henyey_greenstein(float cos_theta, float g) {
    float d = 1.0f + g * g - 2.0f * g * cos_theta;
    return kInvFourPi * (1.0f - g * g) / (d * sqrt(d));
}

REFRACT_INLINE float phase_value(uint model, float cos_theta, float g) {
    if (model == PHASE_SCHLICK_ID) return phase_schlick(cos_theta, g);
    if (model == PHASE_HG_ID) return phase_henyey_greenstein(cos_theta, g);
    return phase_isotropic();
}

// The cosine of a scattering angle drawn from phase_value(model, ., g) by inverting its distribution
// with xi uniform in [0, 1) (OPTICS.md). Henyey-Greenstein's usual form, (1 + g^2 - s^2) / (2 g) with
// s = (1 - g^2) / (1 + g u), divides by g and cancels catastrophically for small |g| in float; expanded
// over the common denominator (1 + g u)^2 it is exact for every g in (-1, 1), 0 included (u itself).
// Clamped: near mu = 1 with g = 0.99 float rounding lands an ulp past it.
REFRACT_INLINE float phase_sample_cos(uint model, float g, float xi) {
    float u = 2.0f * xi - 1.0f;
    float mu = u;
    if (model == PHASE_SCHLICK_ID) mu = (u + g) / (1.0f + g * u);
    if (model == PHASE_HG_ID) {
        float d = 1.0f + g * u;
        mu = (u + 0.5f * g * (3.0f + u * u) + g * g * u + 0.5f * g * g * g * (u * u - 1.0f)) / (d * d);
    }
    return clamp(mu, -1.0f, 1.0f);
}

REFRACT_SHADERS_END

#endif
