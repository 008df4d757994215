#include "passes/transport_pipeline.h"

#include <array>

#include "transport.h"

namespace refract::passes {

TransportPipeline::TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                                     std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes,
                                     const char* name) {
    static_assert(TRANSPORT_CONSTANT_GREY == 0 && TRANSPORT_CONSTANT_COVERAGE_FETCH == 1);
    pipelines_.reserve(4);
    for (uint32_t i = 0; i < 4; ++i) {
        const std::array<uint32_t, 2> constants{i & 1u, (i >> 1) & 1u};
        pipelines_.emplace_back(context, spirv, layout, push_constant_bytes, name, constants);
    }
}

}  // namespace refract::passes
