// Phase functions of the viewing pass, shared with the C++ tests that integrate them over the sphere.
// cos_theta is the cosine between the light's travel direction and the scattered direction (towards the
// eye), so positive g (or Schlick k) favours forward scattering.
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

REFRACT_SHADERS_END

#endif
