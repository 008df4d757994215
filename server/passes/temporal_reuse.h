// Temporal reuse (shaders/temporal_reuse.comp): an interactive frame's jittered samples, reprojected into
// a viewer's full-resolution history and blended with it, then tone-mapped at the viewer's size.
#pragma once

#include "temporal.h"
#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

class TemporalReusePass {
public:
    explicit TemporalReusePass(vk::Context& context);

    struct Buffers {
        const vk::Buffer& params;       // TemporalParams
        const vk::Buffer& samples;      // the sample frame (vec4: radiance, inverse depth)
        const vk::Buffer& history_in;   // the history as it was, and its inverse depths
        const vk::Buffer& depth_in;
        const vk::Buffer& history_out;  // the history made of both, and its inverse depths
        const vk::Buffer& depth_out;
        const vk::Buffer& ldr;          // the history tone-mapped
        const vk::Buffer& neighbourhood;  // the samples' statistics (TemporalNeighbourhoodPass)
    };
    // Over width x height history pixels (TemporalParams::sizes.xy).
    void record(vk::CommandRecorder& recorder, const Buffers& buffers, uint32_t width, uint32_t height) const;

private:
    vk::ComputePipeline pipeline_;
};

}  // namespace refract::passes
