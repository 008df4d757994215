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
    vk::Buffer floor;                 // FLOOR_WORDS uints per floor texel: this light's
    vk::Buffer floor_shadow;          // vec4 per floor texel: the floor shadow's closed form, the frame's lights
    vk::Buffer stats;                 // PhotonStats (host-readable)
    vk::Buffer exits;                 // PhotonExit per photon path when recorded (tests), else one entry
    vk::Buffer light_map_traced;      // float per light-map texel (DirectLightPass)
    vk::Buffer light_map;             // float per light-map texel: where each texel's direct light ends
    vk::Buffer direct_edges;          // WorkListHeader + radiance voxels the direct light's edge crosses
    vk::Buffer direct_reach;          // a bit per radiance-voxel corner (DirectLightPass)
};

// Words of direct_reach for a radiance grid of `radiance_dims` voxels: rows of 32 corners along x.
uint64_t direct_reach_words(vk::Extent3 radiance_dims);

// `radiance_dims`: the radiance grid's voxels; `grey`: grey transport, which keeps no red and green sums.
PhotonAccumulators make_photon_accumulators(vk::Context& context, vk::Extent3 radiance_dims,
                                            uint32_t floor_texels, uint32_t light_map_side,
                                            uint32_t exit_count, bool grey);

// Zeroes the sums, counters and exits before a frame's direct light and photons add to them.
void clear_photon_accumulators(vk::CommandRecorder& recorder, const PhotonAccumulators& accum, bool grey);
// Clears the radiance and floor sums and the photon queue for the next light's photons; the statistics,
// photon exits and the floor shadow's closed form go on.
void clear_for_next_light(vk::CommandRecorder& recorder, const PhotonAccumulators& accum, bool grey);

class PhotonTracePass {
public:
    explicit PhotonTracePass(vk::Context& context);
    // Traces `photon_count` photons into the accumulators (under dispersive transport each parts into a
    // path per channel where it first meets a gradient of n); `sampled_deposits`: one deposit per radiance
    // voxel of path instead of one per voxel crossed (PHOTON_CONSTANT_SAMPLED_DEPOSITS); `random_walks`:
    // photons scatter, up to the frame's bounces (PHOTON_CONSTANT_RANDOM_WALKS). With `between`, in parts
    // of at most kWorkPart photons sized by `pacer`, `between` running after each part but
    // the last. False when `between` stopped the run: part of the photons are traced.
    bool record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const PhotonAccumulators& accum,
                uint32_t photon_count, bool sampled_deposits, bool random_walks,
                const BetweenParts& between, PartPacer& pacer) const;

private:
    TransportPipeline exact_, sampled_, exact_walks_, sampled_walks_;
};

}  // namespace refract::passes
