#include "passes/transport_pipeline.h"

#include <vector>

#include "transport.h"

namespace refract::passes {

TransportPipeline::TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                                     std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes,
                                     const char* name, std::span<const uint32_t> pass_constants) {
    static_assert(TRANSPORT_CONSTANT_GREY == 0 && TRANSPORT_CONSTANT_COVERAGE_FETCH == 1);
    pipelines_.reserve(4);
    for (uint32_t i = 0; i < 4; ++i) {
        std::vector<uint32_t> constants{i & 1u, (i >> 1) & 1u};
        constants.insert(constants.end(), pass_constants.begin(), pass_constants.end());
        pipelines_.emplace_back(context, spirv, layout, push_constant_bytes, name, constants);
    }
}

}  // namespace refract::passes
