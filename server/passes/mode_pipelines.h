// A shader that does several jobs (octree: level-1 ranges, reduce, level map; voxelize: columns,
// combine; index field: one per kind of field), compiled once per job with the job as a
// specialization constant (VOLUME_CONSTANT_MODE in shaders/shared/volume_build.h). lavapipe runs both
// sides of every branch, so a branch on a push constant would run every job in every dispatch. Where the
// jobs are large, a shader is built once per job instead (cmake/shaders.cmake; direct_light.comp).
#pragma once

#include <initializer_list>
#include <span>
#include <vector>

#include "vk/pipeline.h"

namespace refract::passes {

class ModePipelines {
public:
    // One pipeline per name; the i-th does job i: constant `constant_id` is i, the others (from id 0) as
    // `constants` gives them, 0 past its end. Names are string literals (kept, not copied).
    ModePipelines(vk::Context& context, std::span<const uint32_t> spirv, std::span<const vk::BindingLayout> layout,
                  uint32_t push_constant_bytes, std::initializer_list<const char*> names, uint32_t constant_id,
                  std::span<const uint32_t> constants = {});
    const vk::ComputePipeline& operator[](uint32_t mode) const { return pipelines_.at(mode); }

private:
    std::vector<vk::ComputePipeline> pipelines_;
};

}  // namespace refract::passes
