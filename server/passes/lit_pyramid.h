// Pass 5c (lit pyramid): which cells of the grid any photon light reaches, at LIT_LEVELS cell sizes
// (shaders/shared/transport.h), so the viewing pass crosses unlit fog without gathering.
#pragma once

#include "passes/mode_pipelines.h"
#include "vk/commands.h"

namespace refract::passes {

class LitPyramidPass {
public:
    explicit LitPyramidPass(vk::Context& context);
    // Reads the fluence (w) of `flux` as the radiance resolve left it; writes every cell of `lit_blocks`
    // (lit_pyramid_offsets(scene_dims) of them) for a scene of `scene_dims` voxels of its own
    // (TransportParams::lit_grid): 1 where lit at levels above 0, and at level 0 the count of unlit
    // levels (transport.h).
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Image3D& flux,
                const vk::Buffer& lit_blocks, vk::Extent3 scene_dims) const;

private:
    ModePipelines pipelines_;  // by LIT_MODE_*
};

}  // namespace refract::passes
