// Before temporal reuse (shaders/temporal_neighbourhood.comp): per sample of an interactive frame, the
// mean and standard deviation of its 3x3 neighbourhood, which bound the reprojected history.
#pragma once

#include "temporal.h"
#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

class TemporalNeighbourhoodPass {
public:
    explicit TemporalNeighbourhoodPass(vk::Context& context);
    // Over the sample frame's width x height (TemporalParams::sizes.zw); `neighbourhood` holds two vec4
    // per sample.
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Buffer& samples,
                const vk::Buffer& neighbourhood, uint32_t width, uint32_t height) const;

private:
    vk::ComputePipeline pipeline_;
};

}  // namespace refract::passes
