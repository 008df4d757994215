// Viewable PNG slices of volumes for the CLI (index field, radiance grid) and the floor caustic map.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "vk/resources.h"

namespace refract::cli {

enum class SliceAxis { xy, xz };

// Writes the central slice of a scalar volume, mapped linearly from [lo, hi] to a false-colour ramp.
void write_slice_png(const std::string& path, const std::vector<float>& volume, vk::Extent3 dims, SliceAxis axis,
                     float lo, float hi);

// Writes a width x height RGB map (e.g. the floor's irradiance) with a log tone curve relative to `peak`.
void write_map_png(const std::string& path, const std::vector<glm::vec4>& map, uint32_t width, uint32_t height,
                   float peak);

}  // namespace refract::cli
