// The frame's second stage: light through the field (the paper's section 4.3). Each light's unbent
// light in closed form, its photons along curved paths, both resolved into the radiance grid and the
// floor's caustic map (spread, for interactive frames, over boxes sized by the photons behind each). It
// owns those images, the photon accumulators, the environment's map and the frame's parameters, and
// knows what its radiance grid was made with (so an interactive frame may shade from a still frame's
// photons).
#pragma once

#include <optional>
#include <vector>

#include "image/environment_map.h"
#include "passes/environment_light.h"
#include "passes/photon_trace.h"
#include "passes/transport_pipeline.h"
#include "render/frame_inputs.h"
#include "render/frame_recording.h"
#include "render/medium_field.h"
#include "render/pass_kit.h"
#include "render/volume_stage.h"

namespace refract::scene {

struct RunOptions;

class TransportStage {
public:
    explicit TransportStage(PassKit& kit);

    // Drops the photon images: the lattice is new.
    void clear();
    // Whether the resident radiance grid was made with these photon settings (radiance factor, deposits,
    // bounces, kind of transport).
    bool made_for(const FrameInputs::Transport& in, const RunOptions& options) const;
    // Takes the photon settings of this run's grid.
    void make_for(const FrameInputs::Transport& in, const RunOptions& options);
    uint32_t photon_batches() const { return photon_batches_; }
    // `options` with the photon settings the resident radiance grid was made with.
    RunOptions with_resident_photons(RunOptions options) const;

    // The environment's map, made again when what it is made of changed; a placeholder texel when it
    // lights nothing, so the passes always address a buffer. Throws RenderError for an image not given.
    void prepare_environment(const passes::EnvironmentSource& source);
    const passes::EnvironmentLight& environment() const { return environment_light_; }
    // The medium field, made again when the volumes, their `densities` or the lattice changed (uploaded
    // by the next record), and what it emits.
    void prepare_medium_field(const std::map<std::string, protocol::DensityVolume>& volumes,
                              const passes::GridGeometry& lattice, const Densities& densities);
    const MediumEmission& medium_emission() const { return emitted_; }
    // The frame's parameters (with the device addresses they name), the materials and the photon images
    // when the photons are stale.
    void prepare(const FrameInputs::Transport& in, PassSet stale, const RunOptions& options,
                 const passes::GridGeometry& lattice, const VolumeStage& volume);
    // Records the photon passes when stale; false when the run stopped at a part. `resolved` is set once
    // a light's photons replaced the radiance grid's running mean.
    bool record(FrameRecording& recording, PassSet stale, PassSet built, const RunOptions& options,
                const passes::GridGeometry& lattice, const VolumeStage& volume, bool& resolved);

    // What the viewing pass reads: the first light's parameters over the field, and the resolved light.
    passes::TransportInputs view_inputs(const VolumeStage& volume) const;
    const vk::Buffer& params_buffer() const { return params_buffers_.front(); }
    const passes::PhotonAccumulators& accumulators() const { return *accum_; }
    const vk::Image3D& radiance() const { return radiance_; }
    const vk::Image3D& flux() const { return flux_; }
    const vk::Buffer& floor_map() const { return floor_map_; }

    // Read-backs (see SceneGpu).
    uint32_t channels() const { return channels_; }
    bool grey() const { return channels_ == CHANNELS_GREY; }
    const std::vector<shaders::TransportParams>& light_params() const { return light_params_; }
    uint32_t floor_map_side() const { return floor_texels_; }
    std::vector<glm::vec4> read_radiance() const;
    std::vector<glm::vec4> read_flux() const;
    std::vector<glm::vec4> read_floor_map() const;
    std::vector<glm::vec4> read_floor_irradiance() const;
    std::vector<shaders::PhotonExit> read_photon_exits() const;

private:
    void allocate(const passes::GridGeometry& lattice, uint32_t photon_exit_count, bool record_exits,
                  uint32_t radiance_factor, uint32_t channels, bool adaptive_density);
    passes::TransportInputs inputs_for(const vk::Buffer& params, const VolumeStage& volume) const;

    PassKit& kit_;
    uint32_t floor_texels_ = 0, exit_capacity_ = 0, radiance_factor_ = 0;
    bool sampled_deposits_ = false;  // how the photons in the radiance grid were deposited (RunOptions)
    bool adaptive_density_ = false;  // whether the grid holds their light spread (RunOptions)
    uint32_t bounces_ = 0;           // how often they could scatter (photon_bounces)
    uint32_t photon_batches_ = 0;    // how many batches its running mean holds (with kPhotons built)
    passes::PartPacer photon_parts_{TRANSPORT_GROUP_SIZE};  // the photon pass's parts, sized by its last rate
    uint32_t channels_ = CHANNELS_RGB;
    passes::TransportVariant variant_;
    std::vector<shaders::TransportParams> light_params_{shaders::TransportParams{}};
    std::optional<passes::PhotonAccumulators> accum_;
    std::vector<vk::Buffer> params_buffers_;  // one per entry of light_params_
    vk::Buffer materials_;
    vk::Image3D radiance_, flux_;  // radiance_: per-channel fluence, coloured transport only
    vk::Buffer floor_map_;         // floor_texels_ a side (transport.h, floor_map_texel)
    // Under adaptive density, what the resolve writes and the spread reads, and the spread's shares
    // between its two steps (else empty).
    vk::Image3D raw_radiance_, raw_flux_;
    vk::Buffer raw_floor_map_;
    vk::Image3D radiance_shares_, flux_shares_;
    vk::Buffer floor_spread_sums_;
    passes::EnvironmentLight environment_light_;
    vk::Buffer environment_map_;
    std::optional<passes::EnvironmentSource> environment_source_;  // what the map was made of
    // The medium field (medium_field.h): its images, what they were made of, and the staging buffers
    // of an upload the next record makes.
    struct FieldSource {
        passes::GridGeometry lattice;
        std::map<std::string, protocol::DensityVolume> volumes;
        Densities densities;
        bool operator==(const FieldSource&) const = default;
    };
    struct FieldUpload {
        vk::Buffer extinction, scattering, emission;
    };
    vk::Image3D medium_extinction_, medium_scattering_, medium_emission_;
    // The map of blocks and the emitting field voxels (MediumField::blocks, emitters) by device address; a
    // placeholder where none emit.
    vk::Buffer medium_blocks_, medium_emitters_;
    uint32_t emitter_count_ = 0;
    MediumFieldLayout field_layout_;
    MediumEmission emitted_;
    std::optional<FieldSource> field_source_;
    std::optional<FieldUpload> field_upload_;
    std::optional<FieldUpload> uploaded_field_;  // recorded: kept until the next run
};

}  // namespace refract::scene
