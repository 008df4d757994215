// Pass 6 (viewing pass): eye rays through the index field, single scattering from the radiance grid,
// background -> linear radiance per pixel (tone mapping is pass 7, tone_map.h).
#pragma once

#include "passes/photon_trace.h"
#include "passes/view_refine.h"

namespace refract::passes {

struct ViewOutputs {
    const vk::Buffer& hdr;  // vec4 per pixel
    const vk::Buffer& stats;   // PhotonStats; the view pass counts view_steps
    const vk::Buffer& refine;  // WorkListHeader + a pixel index per pixel (transport.h), for adaptive frames
    const vk::Buffer& ends;  // a shaders::ViewEnd per pixel (TRANSPORT_BINDING_VIEW_ENDS), with `ends`
};

class ViewPass {
public:
    explicit ViewPass(vk::Context& context);
    // `adaptive`: trace the pixels with even x and y, then only those others whose traced neighbours
    // differ on screen; interpolate the rest (interactive frames; transport.h, VIEW_PIXELS_*). With
    // `between` (not adaptive), in parts of at most about kViewPart pixels sized by `pacer`,
    // `between` running between parts. False when `between` stopped the run: part of the pixels
    // are traced. `ends`: also write where each eye ray ends (for ViewUpscalePass).
    bool record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const vk::Image3D& radiance,
                const vk::Image3D& flux, const vk::Buffer& floor_map, const ViewOutputs& outputs,
                uint32_t width, uint32_t height, bool adaptive, bool ends, const BetweenParts& between,
                PartPacer& pacer) const;

private:
    vk::Context& context_;
    TransportPipeline pipeline_;
    ViewRefinePass refine_;
};

}  // namespace refract::passes
