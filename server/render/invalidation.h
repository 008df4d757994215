// The paper's passes and which of them an edit of the scene document makes stale.
#pragma once

#include <cstdint>
#include <string>

#include "protocol/scene_document.h"

namespace refract::scene {

// Bit set of passes; each pass depends on every pass before it.
using PassSet = uint32_t;
enum Pass : PassSet {
    kVoxelize = 1u << 0,    // mesh -> supersampled coverage -> Gaussian-smoothed coverage
    kIndexField = 1u << 1,  // coverage (or a procedural/imported field) -> n and grad n per voxel
    kOctree = 1u << 2,      // min/max pyramid of n -> per-voxel leaf level
    kPhotons = 1u << 3,     // photon generation + tracing into the radiance grid and floor caustic map
    kView = 1u << 4,        // eye rays, single scattering -> linear radiance per pixel
    kToneMap = 1u << 5,     // linear radiance x exposure -> sRGB pixels
};
constexpr PassSet kAllPasses = kVoxelize | kIndexField | kOctree | kPhotons | kView | kToneMap;

// Comma-separated names ("voxelize,index_field,octree,photons,view,tone_map") for headers, logs and JSON.
std::string pass_names(PassSet passes);

// The passes that must rerun when the document changes from `before` to `after` (exact: an exposure
// edit is kToneMap only, a camera or image-size edit kView onwards; light, photons, floor, scattering-only material: kPhotons | kView; index,
// mesh, volume: everything; an ior or index-field-kind edit: index field onwards). Asset re-uploads are detected by the renderer, not here.
PassSet passes_invalidated(const protocol::SceneDocument& before, const protocol::SceneDocument& after);

}  // namespace refract::scene
