// Pass 2 (index field): smoothed coverage, a procedural lens or an imported grid -> one rgba32f texel
// per voxel holding n and grad n, plus an r32f coverage image for extinction and scattering.
#pragma once

#include "passes/mode_pipelines.h"
#include "protocol/scene_document.h"
#include "scene/grid_geometry.h"
#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

class IndexFieldPass {
public:
    explicit IndexFieldPass(vk::Context& context);

    // `grid_values` is the imported index grid (same dims as `grid`) for index_field == grid; any small
    // buffer otherwise.
    void record(vk::CommandRecorder& recorder, const protocol::SceneDocument& document,
                const scene::GridGeometry& grid, const vk::Buffer& coverage, const vk::Buffer& grid_values,
                const vk::Image3D& index_field, const vk::Image3D& coverage_image) const;

private:
    ModePipelines pipelines_;  // by INDEX_KIND_*
};

}  // namespace refract::passes
