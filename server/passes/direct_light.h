// Pass 4a (direct light): the light map, the closed-form fluence of the unbent light photons leave to this
// pass, and what the floor's shadow takes from the floor (shaders/shared/transport.h, DIRECT_*), stored
// in their sums before they run.
#pragma once

#include "passes/photon_trace.h"

namespace refract::passes {

class DirectLightPass {
public:
    explicit DirectLightPass(vk::Context& context);
    // Between the accumulators' clear and the photon pass: traces one ray per light-map texel into
    // accum.light_map (which the photons read), flags the floor's shadow and takes its light away in
    // accum.floor, then stores the direct light in accum's radiance sums (the photons add to both).
    void record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const PhotonAccumulators& accum,
                uint32_t light_map_side, vk::Extent3 radiance_dims) const;
    // Where the light is not in closed form: the light map's traced runs and the floor's shadow alone.
    void record_floor_shadow(vk::CommandRecorder& recorder, const TransportInputs& inputs,
                             const PhotonAccumulators& accum, uint32_t light_map_side) const;

private:
    void record_floor_shadow_after_trace(vk::CommandRecorder& recorder, const TransportInputs& inputs,
                                         const PhotonAccumulators& accum) const;
    TransportPipeline trace_, margin_, reach_, deposit_, deposit_full_, edge_, floor_corners_, floor_shadow_;  // by DIRECT_MODE_*
};

}  // namespace refract::passes
