#include "passes/environment_light.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace refract::passes {

EnvironmentLight make_environment_light(const EnvironmentSource& source) {
    EnvironmentLight light;
    if (source.kind == EnvironmentSource::Kind::sky) {
        light.texels.assign(2, glm::vec4(0.0f));
        return light;
    }
    std::vector<float> rgb;
    if (source.kind == EnvironmentSource::Kind::uniform) {
        light.width = 1;
        light.height = 2;
        for (int row = 0; row < 2; ++row)
            for (int c = 0; c < 3; ++c) rgb.push_back(static_cast<float>(source.color[c]));
    } else {
        if (source.image == nullptr || source.image->width == 0)
            throw std::invalid_argument("environment image '" + source.name + "' was not given");
        light.width = source.image->width;
        light.height = source.image->height;
        rgb = source.image->rgb;
    }
    const uint32_t width = light.width, height = light.height;
    const double intensity = source.intensity;
    const double pi = std::numbers::pi, column_angle = 2.0 * pi / width;
    const bool floor_hides_below = source.floor_hides_below;
    light.texels.resize(size_t{width} * height + height);
    std::vector<double> row_sums(height, 0.0);
    glm::dvec3 irradiance(0.0);
    for (uint32_t v = 0; v < height; ++v) {
        const double top = std::cos(pi * v / height), bottom = std::cos(pi * (v + 1) / height);
        const double sampled_bottom = floor_hides_below ? std::max(bottom, 0.0) : bottom;
        const double pixel_angle = column_angle * std::max(top - sampled_bottom, 0.0);
        // Integral of cos theta over the pixel's part above the horizon: the floor's view of it.
        const double upper_top = std::max(top, 0.0), upper_bottom = std::max(bottom, 0.0);
        const double pixel_cosine = column_angle * 0.5 * (upper_top * upper_top - upper_bottom * upper_bottom);
        double row = 0.0;
        for (uint32_t u = 0; u < width; ++u) {
            const size_t pixel = size_t{v} * width + u;
            const glm::dvec3 radiance = glm::dvec3(rgb[3 * pixel], rgb[3 * pixel + 1], rgb[3 * pixel + 2]) * intensity;
            const double mean = (radiance.r + radiance.g + radiance.b) / 3.0;
            if (mean > 0.0 && pixel_angle > 0.0)
                light.channel_ratio = std::max(light.channel_ratio, std::max({radiance.r, radiance.g, radiance.b}) / mean);
            row += mean * pixel_angle;
            irradiance += radiance * pixel_cosine;
            light.texels[pixel] = glm::vec4(glm::vec3(radiance), static_cast<float>(row));
        }
        for (uint32_t u = 0; u < width; ++u) {
            glm::vec4& texel = light.texels[size_t{v} * width + u];
            texel.w = row > 0.0 ? static_cast<float>(static_cast<double>(texel.w) / row) : 1.0f;
        }
        row_sums[v] = row;
        light.sampled += row;
        light.texels[size_t{width} * height + v] =
            glm::vec4(0.0f, static_cast<float>(top), static_cast<float>(sampled_bottom), 0.0f);
    }
    double cumulative = 0.0;
    for (uint32_t v = 0; v < height; ++v) {
        cumulative += row_sums[v];
        light.texels[size_t{width} * height + v].x =
            light.sampled > 0.0 ? static_cast<float>(cumulative / light.sampled) : 1.0f;
    }
    light.floor_irradiance = glm::vec3(irradiance);
    if (!source.lights) {  // a backdrop only: the map without its power
        light.sampled = 0.0;
        light.floor_irradiance = glm::vec3(0.0f);
    }
    return light;
}

}  // namespace refract::passes
