// Pass 6 (viewing pass): eye rays through the index field, single scattering from the radiance grid,
// background, exposure and tone mapping -> linear HDR and sRGB8 pixels.
#pragma once

#include "passes/photon_trace.h"

namespace refract::passes {

struct ViewOutputs {
    const vk::Buffer& hdr;  // vec4 per pixel
    const vk::Buffer& ldr;  // RGBA8 per pixel
    const vk::Buffer& stats;  // PhotonStats; the view pass counts view_steps
    const vk::Buffer& lit_blocks;
};

class ViewPass {
public:
    explicit ViewPass(vk::Context& context);
    void record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const vk::Image3D& radiance,
                const vk::Image3D& flux, const vk::Image3D& floor_map, const ViewOutputs& outputs,
                uint32_t width, uint32_t height) const;

private:
    TransportPipeline pipeline_;
};

}  // namespace refract::passes
