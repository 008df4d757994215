#include "passes/mode_pipelines.h"

#include <vector>

namespace refract::passes {

ModePipelines::ModePipelines(vk::Context& context, std::span<const uint32_t> spirv,
                             std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes,
                             std::initializer_list<const char*> names, uint32_t constant_id) {
    pipelines_.reserve(names.size());
    std::vector<uint32_t> constants(constant_id + 1, 0u);
    for (const char* name : names) {
        pipelines_.emplace_back(context, spirv, layout, push_constant_bytes, name, constants);
        ++constants.back();
    }
}

}  // namespace refract::passes
