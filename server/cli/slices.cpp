#include "cli/slices.h"

#include <algorithm>
#include <cmath>

#include "image/png.h"

namespace refract::cli {
namespace {

// A perceptually ordered ramp (black, blue, magenta, orange, white) for scalar slices.
uint32_t ramp(float t) {
    t = std::clamp(t, 0.0f, 1.0f);
    const glm::vec3 stops[] = {{0.0f, 0.0f, 0.02f}, {0.15f, 0.1f, 0.5f}, {0.75f, 0.15f, 0.5f},
                               {1.0f, 0.6f, 0.1f}, {1.0f, 1.0f, 0.9f}};
    const float x = t * 4.0f;
    const int i = std::min(3, static_cast<int>(x));
    const glm::vec3 c = glm::mix(stops[i], stops[i + 1], x - static_cast<float>(i));
    auto byte = [](float v) { return static_cast<uint32_t>(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f); };
    return byte(c.r) | (byte(c.g) << 8) | (byte(c.b) << 16) | 0xff000000u;
}

}  // namespace

void write_slice_png(const std::string& path, const std::vector<float>& volume, vk::Extent3 dims, SliceAxis axis,
                     float lo, float hi) {
    const float span = hi > lo ? hi - lo : 1.0f;
    const uint32_t width = dims.x;
    const uint32_t height = axis == SliceAxis::xy ? dims.y : dims.z;
    std::vector<uint32_t> pixels(size_t{width} * height);
    for (uint32_t row = 0; row < height; ++row)
        for (uint32_t x = 0; x < width; ++x) {
            // Image rows go top to bottom; put +y (or +z) up.
            const uint32_t b = height - 1 - row;
            const size_t index = axis == SliceAxis::xy
                                     ? (size_t{dims.z / 2} * dims.y + b) * dims.x + x
                                     : (size_t{b} * dims.y + dims.y / 2) * dims.x + x;
            pixels[size_t{row} * width + x] = ramp((volume[index] - lo) / span);
        }
    image::write_file(path, image::encode_png(pixels, width, height));
}

void write_map_png(const std::string& path, const std::vector<glm::vec4>& map, uint32_t width, uint32_t height,
                   float peak) {
    std::vector<uint32_t> pixels(size_t{width} * height);
    const float scale = peak > 0.0f ? 1.0f / peak : 1.0f;
    for (uint32_t y = 0; y < height; ++y)
        for (uint32_t x = 0; x < width; ++x) {
            const glm::vec4 v = map[size_t{y} * width + x];
            const float luminance = (v.r + v.g + v.b) / 3.0f * scale;
            // log curve: 1/1000 of the peak maps to black.
            pixels[size_t{y} * width + x] = ramp(std::log10(std::max(luminance, 1e-3f)) / 3.0f + 1.0f);
        }
    image::write_file(path, image::encode_png(pixels, width, height));
}

}  // namespace refract::cli
