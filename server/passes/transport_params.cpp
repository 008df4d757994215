#include "passes/transport_params.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace refract::passes {

uint32_t floor_map_texels(const passes::GridGeometry& grid) {
    // The map spans up to 4 grid extents; about two voxels per texel keeps the photon noise down.
    const float extent = static_cast<float>(std::max({grid.dims.x, grid.dims.y, grid.dims.z}));
    return std::clamp(static_cast<uint32_t>(extent * 4.0f / 2.0f), 64u, 1024u);
}

uint32_t light_map_capacity(const passes::GridGeometry& grid) {
    // About a texel per voxel across the grid.
    return std::clamp(std::max({grid.dims.x, grid.dims.y, grid.dims.z}), 32u, 512u);
}

uint32_t light_map_texels(const passes::GridGeometry& grid, uint32_t photons) {
    // No more rays than a sixteenth of the photons: the map costs a ray each, and a coarser one only
    // leaves more of the light to the photons.
    const auto quarter_root = static_cast<uint32_t>(std::sqrt(static_cast<double>(photons)) / 4.0);
    return std::max(std::min(light_map_capacity(grid), quarter_root), 32u);
}

uint32_t photon_exit_count(uint32_t photons, uint32_t channels) {
    return channels == CHANNELS_DISPERSIVE ? 3 * photons : photons;
}

glm::vec3 dispersion_scales(double abbe) {
    if (abbe <= 0.0) return glm::vec3(1.0f);
    // Cauchy's n(lambda) = A + B / lambda^2 through n_d (587.56 nm) with Abbe number
    // V = (n_d - 1) / (n_F - n_C) is n(lambda) - 1 = (n_d - 1) (1 + k(lambda) / V), with
    // k = (lambda^-2 - lambda_d^-2) / (lambda_F^-2 - lambda_C^-2): the deviation from vacuum scales by
    // 1 + k / V. Applied to the contrast against the medium, it is exact for an object in air and
    // makes every point of a graded field disperse like a glass of that Abbe number. Each channel
    // takes the dominant wavelength of its sRGB primary.
    auto inverse_square = [](double nm) { return 1.0 / (nm * nm); };
    const double d = inverse_square(587.56), f_minus_c = inverse_square(486.13) - inverse_square(656.27);
    glm::vec3 scales;
    const double channel_nm[3] = {611.0, 549.0, 464.0};
    for (int c = 0; c < 3; ++c)
        scales[c] = static_cast<float>(1.0 + (inverse_square(channel_nm[c]) - d) / f_minus_c / abbe);
    return scales;
}

glm::vec2 view_sample_offset(uint32_t index) {
    if (index == 0) return glm::vec2(0.0f);
    auto radical_inverse = [](uint32_t i, uint32_t base) {
        float inverse = 1.0f / static_cast<float>(base), f = inverse, r = 0.0f;
        for (; i > 0; i /= base, f *= inverse) r += f * static_cast<float>(i % base);
        return r;
    };
    return glm::vec2(radical_inverse(index, 2), radical_inverse(index, 3)) - 0.5f;
}

std::vector<uint32_t> photon_shares(uint32_t photons, const std::vector<double>& powers) {
    double total = 0.0;
    for (double p : powers) total += p;
    std::vector<uint32_t> shares(powers.size(), 0u);
    if (shares.empty()) return shares;
    if (!(total > 0.0)) {
        shares[0] = photons;  // nothing is lit: the first light's photons carry no flux
        return shares;
    }
    for (size_t i = 0; i < powers.size(); ++i)
        if (powers[i] > 0.0)
            shares[i] = std::max(1u, static_cast<uint32_t>(std::llround(static_cast<double>(photons) * powers[i] / total)));
    return shares;
}

}  // namespace refract::passes
