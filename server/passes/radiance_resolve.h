// Pass 5b (radiance resolve): fixed-point photon sums -> the radiance grid in physical units (fluence
// rate W/m^2 and mean light direction per voxel) and the floor irradiance map.
#pragma once

#include "passes/photon_trace.h"

namespace refract::passes {

class RadianceResolvePass {
public:
    explicit RadianceResolvePass(vk::Context& context);
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, const PhotonAccumulators& accum,
                const vk::Image3D& radiance, const vk::Image3D& direction, const vk::Image3D& floor_map) const;

private:
    vk::ComputePipeline pipeline_;
};

}  // namespace refract::passes
