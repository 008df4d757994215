#include "passes/mode_pipelines.h"

#include <algorithm>
#include <vector>

namespace refract::passes {

ModePipelines::ModePipelines(vk::Context& context, std::span<const uint32_t> spirv,
                             std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes,
                             std::initializer_list<const char*> names, uint32_t constant_id,
                             std::span<const uint32_t> constants) {
    pipelines_.reserve(names.size());
    std::vector<uint32_t> values(constants.begin(), constants.end());
    values.resize(std::max(values.size(), size_t{constant_id} + 1), 0u);
    values[constant_id] = 0u;
    for (const char* name : names) {
        pipelines_.emplace_back(context, spirv, layout, push_constant_bytes, name, values);
        ++values[constant_id];
    }
}

}  // namespace refract::passes
