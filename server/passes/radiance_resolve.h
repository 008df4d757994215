// Pass 5b (radiance resolve): fixed-point photon sums -> the radiance grid in physical units (fluence
// rate and net flux vector per voxel, W/m^2) and the floor irradiance map.
#pragma once

#include <vector>

#include "passes/photon_trace.h"

namespace refract::passes {

class RadianceResolvePass {
public:
    explicit RadianceResolvePass(vk::Context& context);
    // `radiance` (rgb fluence) is written by coloured transport only; grey transport binds any image.
    // `floor_map`: `floor_side` texels a side (transport.h, floor_map_texel). `add_floor_shadow`: the frame's
    // last light, and no spread follows: the floor shadow's closed form (accum.floor_shadow) joins the floor
    // map.
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, const PhotonAccumulators& accum,
                bool grey, const vk::Image3D& radiance, const vk::Image3D& flux, const vk::Buffer& floor_map,
                uint32_t floor_side, bool add_floor_shadow) const;

private:
    // Indexed grey + 2 x floor: grey or coloured transport, radiance-grid voxels or floor-map texels.
    std::vector<vk::ComputePipeline> pipelines_;
};

}  // namespace refract::passes
