// Pass 4a (direct light): the light map, and the closed-form fluence of the unbent light photons leave to
// this pass (shaders/shared/transport.h, DIRECT_*), stored in their sums before they run.
#pragma once

#include "passes/photon_trace.h"

namespace refract::passes {

class DirectLightPass {
public:
    explicit DirectLightPass(vk::Context& context);
    // Between the accumulators' clear and the photon pass: traces one ray per light-map texel into
    // accum.light_map (which the photons read), then stores the direct light in accum's radiance sums
    // (which the photons add to).
    void record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const PhotonAccumulators& accum,
                uint32_t light_map_side, vk::Extent3 radiance_dims) const;

private:
    TransportPipeline trace_, margin_, reach_, deposit_, deposit_full_, edge_;  // by DIRECT_MODE_*
};

}  // namespace refract::passes
