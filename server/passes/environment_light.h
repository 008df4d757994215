// The environment as a light: its map as the photon and viewing passes read it (transport.h,
// ENVIRONMENT_ROWS_AT), with the tables that sample photons from it in proportion to its power, and the
// sums the frame's parameters need. A uniform environment is a map of one column and two rows (above and
// below the horizon); the built-in sky lights nothing.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "image/environment_map.h"
#include "transport.h"

namespace refract::passes {

struct EnvironmentLight {
    uint32_t width = 0, height = 0;  // the map's; 0 for the sky
    // The map then the rows (transport.h); one zero texel and row for the sky, so the passes always have
    // a buffer to address.
    std::vector<glm::vec4> texels;
    // Integral of the colour's mean radiance over the sampled directions (W/m^2): the power crossing a
    // unit area facing each of them, summed; 0 when it lights nothing (environment_lights).
    double sampled = 0.0;
    // The largest ratio of a sampled pixel's brightest channel to its mean (1 for grey, at most 3).
    double channel_ratio = 1.0;
    // Irradiance on a horizontal surface open to the upper hemisphere (W/m^2, per channel).
    glm::vec3 floor_irradiance{0.0f};
    bool lights() const { return sampled > 0.0; }
};

// What an environment is made of: the render side fills it from the scene document.
struct EnvironmentSource {
    enum class Kind { sky, uniform, image } kind = Kind::sky;
    glm::dvec3 color{0.0};                          // a uniform environment's radiance
    const image::EnvironmentMap* image = nullptr;   // an image environment's map
    std::string name;                               // the image's, for messages
    double intensity = 1.0;
    bool lights = false;              // it lights the scene; else it is a backdrop only, without its power
    bool floor_hides_below = false;   // the floor is on: photons come only from above the horizon, as the
                                      // floor, an infinite plane, hides the rest from everything above it
    bool operator==(const EnvironmentSource&) const = default;
};

// The environment made of `source`.
EnvironmentLight make_environment_light(const EnvironmentSource& source);

}  // namespace refract::passes
