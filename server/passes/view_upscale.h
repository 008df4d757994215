// Pass 6c (view upscale): an interactive frame traced smaller than its viewer's image, brought to the
// viewer's size (shaders/view_upscale.comp): the light gathered along the traced eye rays and their
// transmittance interpolated, the floor or sky at their straight ends evaluated for every pixel, then
// tone-mapped. Reads what the viewing pass wrote with ViewPush::ends.
#pragma once

#include "passes/transport_pipeline.h"
#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

struct UpscaleBuffers {
    const vk::Buffer& ends;        // where its eye rays end (TRANSPORT_BINDING_VIEW_ENDS)
    const vk::Buffer& viewer_hdr;  // vec4 per viewer pixel (w: 0, no inverse depth)
    const vk::Buffer& viewer_ldr;  // sRGB RGBA8 per viewer pixel
};

class ViewUpscalePass {
public:
    explicit ViewUpscalePass(vk::Context& context);
    // Over width x height viewer pixels; the traced frame's size, camera and exposure are the params'.
    void record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const vk::Image3D& floor_map,
                const UpscaleBuffers& buffers, uint32_t width, uint32_t height) const;

private:
    vk::ComputePipeline pipeline_;  // one for every transport variant: it reads none of their constants
};

}  // namespace refract::passes
