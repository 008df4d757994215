// Passes 4-5 (photon generation + tracing): fills the radiance grid's fixed-point sums and the floor
// caustic map from one dispatch, one thread per photon.
#pragma once

#include "vk/commands.h"
#include "passes/transport_pipeline.h"
#include "vk/pipeline.h"

namespace refract::passes {

// Everything the photon pass writes and the resolve pass reads.
struct PhotonAccumulators {
    vk::Buffer red_green;             // packed 64-bit sums per voxel (shaders/shared/transport.h); one word when grey
    vk::Buffer flux;                  // RADIANCE_FLUX_WORDS packed 64-bit sums per voxel: blue (grey: mean) + net flux
    vk::Buffer floor;                 // 3 uints per floor texel
    vk::Buffer stats;                 // PhotonStats (host-readable)
    vk::Buffer exits;                 // PhotonExit per photon when recorded (tests), else one entry
    vk::Buffer lit_blocks;            // the lit pyramid (transport.h), written by LitPyramidPass
};

// `dims`: the index field's voxels (lit blocks cover those); `radiance_dims`: the radiance grid's; `grey`:
// grey transport, which keeps no red and green sums.
PhotonAccumulators make_photon_accumulators(vk::Context& context, vk::Extent3 dims, vk::Extent3 radiance_dims,
                                            uint32_t floor_texels, uint32_t exit_count, bool grey);

// Inputs shared by the photon and viewing passes.
struct TransportInputs {
    const vk::Buffer& params;
    const vk::Image3D& index_field;
    const vk::Image3D& coverage;
    const vk::Buffer& levels;
    VkSampler sampler;
    TransportVariant variant;
};

class PhotonTracePass {
public:
    explicit PhotonTracePass(vk::Context& context);
    // Clears the accumulators and traces `photon_count` photons; `sampled_deposits`: one deposit per
    // radiance voxel of path instead of one per voxel crossed (PHOTON_CONSTANT_SAMPLED_DEPOSITS).
    void record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const PhotonAccumulators& accum,
                uint32_t photon_count, bool sampled_deposits) const;

private:
    TransportPipeline exact_, sampled_;
};

}  // namespace refract::passes
