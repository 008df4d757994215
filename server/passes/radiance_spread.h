// Pass 5b' (adaptive density, interactive frames): the resolved radiance grid with each voxel's light
// spread over a box sized by the photon tracks behind it (shaders/radiance_spread.comp): smooth where
// photons are few, sharp where many, the grid's total unchanged.
#pragma once

#include <vector>

#include "vk/commands.h"
#include "vk/pipeline.h"
#include "vk/resources.h"

namespace refract::passes {

// The resolve's images: per-channel fluence (coloured transport only; grey transport binds any image),
// net flux and fluence, the floor map.
struct SpreadImages {
    const vk::Image3D& radiance;
    const vk::Image3D& flux;
    const vk::Image3D& floor_map;
};

class RadianceSpreadPass {
public:
    explicit RadianceSpreadPass(vk::Context& context);
    // Reads `raw` (as the resolve left it) and writes `out`, of the same sizes; `shares` (rgba32f, the
    // same sizes) holds what each source gives the voxels or texels it reaches, between the two steps;
    // `floor_shadow` (PhotonAccumulators::floor_shadow) is added to the spread floor map.
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, bool grey, const SpreadImages& raw,
                const SpreadImages& shares, const SpreadImages& out, const vk::Buffer& floor_shadow) const;

private:
    // By job (voxels, floor texels), step (shares, gather) and channels (coloured, grey).
    std::vector<vk::ComputePipeline> pipelines_;
};

}  // namespace refract::passes
