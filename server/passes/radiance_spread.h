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
// net flux and fluence; and the floor map (transport.h, floor_map_texel) of `floor_side` texels a side.
struct SpreadImages {
    const vk::Image3D& radiance;
    const vk::Image3D& flux;
    const vk::Buffer& floor_map;
    uint32_t floor_side;
};

// Between the spread's steps: what each voxel gives the voxels its box reaches (rgba32f images of the
// resolve's sizes), and the floor map's sums (floor_spread_bytes; transport.h,
// TRANSPORT_BINDING_SPREAD_FLOOR_SUMS).
struct SpreadShares {
    const vk::Image3D& radiance;
    const vk::Image3D& flux;
    const vk::Buffer& floor_sums;
};

// The bytes of the floor map's spread sums for a map of `side` x `side` texels.
uint64_t floor_spread_bytes(uint32_t side);

class RadianceSpreadPass {
public:
    explicit RadianceSpreadPass(vk::Context& context);
    // Reads `raw` (as the resolve left it) and writes `out`, of the same sizes, through `shares`;
    // `floor_shadow` (PhotonAccumulators::floor_shadow) is added to the spread floor map.
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, bool grey, const SpreadImages& raw,
                const SpreadShares& shares, const SpreadImages& out, const vk::Buffer& floor_shadow) const;

private:
    // By job (voxels, floor texels), step and channels (coloured, grey).
    std::vector<vk::ComputePipeline> pipelines_;
};

}  // namespace refract::passes
