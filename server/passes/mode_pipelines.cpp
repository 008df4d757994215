#include "passes/mode_pipelines.h"

#include <array>

#include "volume_build.h"

namespace refract::passes {

ModePipelines::ModePipelines(vk::Context& context, std::span<const uint32_t> spirv,
                             std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes,
                             std::initializer_list<const char*> names) {
    static_assert(VOLUME_CONSTANT_MODE == 0);
    pipelines_.reserve(names.size());
    uint32_t mode = 0;
    for (const char* name : names) {
        const std::array<uint32_t, 1> constants{mode++};
        pipelines_.emplace_back(context, spirv, layout, push_constant_bytes, name, constants);
    }
}

}  // namespace refract::passes
