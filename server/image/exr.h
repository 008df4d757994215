// Frame encoding for compositing tools: OpenEXR, linear half-float RGB (ZIP, lossless), with the frame's
// metadata as header attributes.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "protocol/scene_document.h"

namespace refract::image {

// Header attributes besides the format's own, by name: text, numbers (doubles) and 3-vectors.
struct ExrAttributes {
    std::vector<std::pair<std::string, std::string>> text;
    std::vector<std::pair<std::string, double>> numbers;
    std::vector<std::pair<std::string, std::array<double, 3>>> vectors;
};

// A frame's metadata as header attributes: refractLevel, refractPhotons, refractRevision (when not 0),
// refractExposure (the stops the PNG applies), cameraPosition, cameraTarget, cameraUp, cameraFovDeg, software.
ExrAttributes frame_attributes(const protocol::SceneDocument& document, uint32_t level, uint64_t photons,
                               uint64_t revision = 0);

// `rgba` holds 4 floats per pixel (alpha ignored), top row first. Throws std::runtime_error from OpenEXR.
std::string encode_exr(std::span<const float> rgba, uint32_t width, uint32_t height, const ExrAttributes& attributes);

}  // namespace refract::image
