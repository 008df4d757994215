// Pass 7 (tone mapping): linear radiance x exposure -> ACES-fit tone curve -> sRGB8 pixels
// (shaders/tone_map.comp). Split from the viewing pass so that a purely display edit (exposure) reruns
// only this.
#pragma once

#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

class ToneMapPass {
public:
    explicit ToneMapPass(vk::Context& context);
    // Writes `ldr` (RGBA8 per pixel) from `hdr` (vec4 per pixel) at the exposure and size in `params`.
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Buffer& hdr, const vk::Buffer& ldr,
                uint32_t width, uint32_t height) const;

private:
    vk::ComputePipeline pipeline_;
};

}  // namespace refract::passes
