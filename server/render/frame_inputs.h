// The scene document turned once, at the top of a run, into what each stage of the frame reads. The
// stages and passes never see the document.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "passes/environment_light.h"
#include "passes/grid_geometry.h"
#include "passes/index_field.h"
#include "protocol/scene_document.h"
#include "render/medium_field.h"
#include "transport.h"

namespace refract::scene {

struct RunOptions;

struct FrameInputs {
    // Voxelize, index field, octree.
    struct Volume {
        bool imported = false;   // the field is an imported index grid (the scene's one object)
        double smoothing = 0.0;  // volume.smoothing: the lattice Gaussian's sigma (voxels)
        double medium_ior = 1.0;
        passes::FieldShape medium;  // the medium as a field: uniform, its index
        // Each object's field shape, in name order (so object numbers count from 1 along it).
        std::vector<std::pair<std::string, passes::FieldShape>> objects;
        float octree_epsilon = 0.0f;
    };
    // Direct light, photons, resolve.
    struct Transport {
        uint32_t channels = CHANNELS_RGB;  // how the colour channels travel (transport_channels)
        uint32_t bounces = 0;              // scattering events per photon (photon_bounces)
        bool fresnel = false, film = false;
        // The frame's parameters per light whose photons run (make_transport_params); the first serves the
        // view and tone map too. Device addresses are the stages' to fill.
        std::vector<shaders::TransportParams> lights;
        std::vector<shaders::Material> materials;  // several objects: by object number; empty for one
        // The volumes (TRANSPORT_CONSTANT_MEDIUM_FIELD when any), resampled by the stage into the medium field.
        std::map<std::string, protocol::DensityVolume> volumes;
    };
    // View, tone map.
    struct View {
        uint32_t width = 0, height = 0;
    };
    Volume volume;
    Transport transport;
    View view;
};

// An object as the index-field pass makes its field.
passes::FieldShape field_shape(const protocol::Object& object);

FrameInputs::Volume volume_inputs(const protocol::SceneDocument& document);

// The photon settings alone (channels and bounces): what decides whether a resident radiance grid
// serves a run with `options`.
FrameInputs::Transport photon_settings(const protocol::SceneDocument& document, const RunOptions& options);

// The transport's inputs over the lattice `grid`, lit by `environment` (made of environment_source) and
// by what the volumes emit (the medium field's, made of the document's volumes on `grid`); `bending`:
// where n may vary (VolumeStage::bending), where the lights' photons go.
FrameInputs::Transport transport_inputs(const protocol::SceneDocument& document,
                                        const passes::GridGeometry& grid,
                                        const passes::EnvironmentLight& environment,
                                        const MediumEmission& emitted, const std::vector<glm::vec4>& bending,
                                        const RunOptions& options);

}  // namespace refract::scene
