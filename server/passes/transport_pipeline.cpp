#include "passes/transport_pipeline.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "transport.h"

namespace refract::passes {

uint32_t PartPacer::next(uint32_t largest) const {
    if (!paced_ || items_per_ms_ <= 0.0) return largest;
    const double items = std::max(1.0, std::floor(items_per_ms_ * kPartMs / granule_)) * granule_;
    return static_cast<uint32_t>(std::min(items, static_cast<double>(largest)));
}

bool PartPacer::between(const BetweenParts& between, uint32_t items) {
    if (between()) return true;
    const auto now = std::chrono::steady_clock::now();
    items_per_ms_ = items / std::max(std::chrono::duration<double, std::milli>(now - started_).count(), 1e-3);
    started_ = now;
    return false;
}

TransportPipeline::TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                                     std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes,
                                     const char* name, std::span<const uint32_t> pass_constants)
    : context_(context),
      spirv_(spirv),
      layout_(layout.begin(), layout.end()),
      push_constant_bytes_(push_constant_bytes),
      name_(name),
      pass_constants_(pass_constants.begin(), pass_constants.end()) {}

const vk::ComputePipeline& TransportPipeline::operator()(TransportVariant variant) const {
    static_assert(TRANSPORT_CONSTANT_CHANNELS == 0 && TRANSPORT_CONSTANT_COVERAGE_FETCH == 1 &&
                  TRANSPORT_CONSTANT_FRESNEL == 2 && TRANSPORT_CONSTANT_FILM == 3 &&
                  TRANSPORT_CONSTANT_MATERIALS == 4 && TRANSPORT_CONSTANT_FIELD_ATLAS == 5 &&
                  TRANSPORT_CONSTANT_MEDIUM_FIELD == 6 && TRANSPORT_CONSTANT_MEDIUM_FADE == 7 &&
                  TRANSPORT_CONSTANT_COUNT == 8);
    if (variant.channels > CHANNELS_DISPERSIVE)
        throw std::invalid_argument(std::string(name_) + ": no transport channels " + std::to_string(variant.channels));
    const bool film = variant.fresnel && variant.film;
    const uint32_t boundary = film ? 2u : (variant.fresnel ? 1u : 0u);
    const bool field_atlas = variant.materials && variant.field_atlas;
    std::optional<vk::ComputePipeline>& pipeline =
        pipelines_[variant.channels + (variant.coverage_fetch ? 3u : 0u) + 6u * boundary + (variant.materials ? 18u : 0u) +
                   (field_atlas ? 18u : 0u) + (variant.medium_field ? 54u : 0u) + (variant.medium_fade ? 108u : 0u)];
    if (!pipeline) {
        std::vector<uint32_t> constants{variant.channels, variant.coverage_fetch ? 1u : 0u, variant.fresnel ? 1u : 0u,
                                        film ? 1u : 0u, variant.materials ? 1u : 0u, field_atlas ? 1u : 0u,
                                        variant.medium_field ? 1u : 0u, variant.medium_fade ? 1u : 0u};
        constants.insert(constants.end(), pass_constants_.begin(), pass_constants_.end());
        pipeline.emplace(context_, spirv_, layout_, push_constant_bytes_, name_, constants);
    }
    return *pipeline;
}

}  // namespace refract::passes
