// The frame's first stage: the objects' meshes voxelized into smoothed coverage, the refractive index
// field composed of them (or imported), and the octree over it (the paper's sections 4.1-4.2). It owns
// the field images, each object's coverage and the octree, and decides which of them an edit remakes:
// an edit of one object of several voxelizes that one and recomposes the field over its box only.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "assets/index_grid.h"
#include "passes/grid_geometry.h"
#include "passes/index_field.h"
#include "passes/voxelize.h"
#include "render/field_atlas.h"
#include "render/frame_inputs.h"
#include "render/frame_recording.h"
#include "render/object_mesh.h"
#include "render/pass_kit.h"

namespace refract::scene {

// Where the field of objects in `boxes` lives: a sparse atlas of their boxes (render/field_atlas.h) no
// wider than `max_side` where it holds under half the lattice's voxels, else the dense lattice; the
// lattice always for one object or an imported grid (`dense`). Throws RenderError when the atlas would
// not fit `max_side`.
FieldAtlas field_atlas_for(const passes::GridGeometry& lattice, const std::map<std::string, passes::ObjectBox>& boxes,
                           bool dense, uint32_t max_side);

// The voxels around an object's world bounds its box takes (object_box) for a smoothing of `sigma`
// voxels: where the B-spline and the lattice Gaussian (passes::VoxelizePass) leave coverage, and one
// more for the index field's central differences.
uint32_t object_apron(double sigma);

// The objects' boxes in `lattice`, by name: the whole lattice for the one object of a scene of one.
std::map<std::string, passes::ObjectBox> object_boxes(const passes::GridGeometry& lattice, const WorldMeshes& worlds,
                                                      double sigma);

// World spheres (centre, radius) that hold every gradient of n and every object's coverage in `lattice`:
// each object's world mesh (and a procedural lens's own sphere) grown by its apron.
std::vector<glm::vec4> bending_spheres(const passes::GridGeometry& lattice, const FrameInputs::Volume& in,
                                       const WorldMeshes& worlds);

// How a frame's voxelize pass runs (RunOptions::voxelize).
struct VoxelizeOptions {
    // Every object voxelized anew, even one whose coverage still fits (what a benchmark of a whole
    // rebuild measures).
    bool again = false;
    // S x S rays per voxel column and axis; previews take passes::VoxelizePass::kPreviewSubsamples.
    uint32_t subsamples = passes::VoxelizePass::kSubsamples;
};

class VolumeStage {
public:
    explicit VolumeStage(PassKit& kit);

    // Drops everything: the lattice is new.
    void clear();
    // Lays the field out over `lattice` for the objects' boxes when the voxelize pass is stale. True when
    // that makes new field images (the index field and octree are then not built).
    bool lay_out(const passes::GridGeometry& lattice, const FrameInputs::Volume& in, const WorldMeshes& worlds,
                 PassSet stale, PassSet built);
    // Where n may vary, as of the last lay_out that voxelized (bending_spheres); empty for an imported grid,
    // which may vary anywhere.
    const std::vector<glm::vec4>& bending() const { return bending_; }
    // Records the stale volume passes (`built`: what is resident and whole). False when the run stopped
    // at a part. `voxelized` gets the objects voxelized, by name.
    bool record(FrameRecording& recording, PassSet stale, PassSet built, const FrameInputs::Volume& in,
                const WorldMeshes& worlds, const IndexGrid* grid_asset, const VoxelizeOptions& voxelize,
                std::vector<std::string>& voxelized);
    // Releases what the run's recorded commands used (after they completed).
    void end_run();

    bool has_field() const { return index_field_.get() != VK_NULL_HANDLE; }
    const FieldAtlas& atlas() const { return atlas_; }
    const vk::Buffer& atlas_map() const { return atlas_map_; }
    const vk::Image3D& index_field() const { return index_field_; }
    const vk::Image3D& coverage_image() const { return coverage_image_; }
    const vk::Buffer& levels() const { return levels_; }

    // Read-backs over the lattice (see SceneGpu).
    std::vector<float> read_coverage() const;
    std::vector<uint32_t> read_object_numbers() const;
    std::vector<glm::vec4> read_index_field() const;
    std::vector<uint32_t> read_levels() const;
    std::vector<glm::vec2> read_pyramid() const;

private:
    void allocate_field(FieldAtlas atlas);
    void record_voxelize(vk::CommandRecorder& recorder, const FrameInputs::Volume& in, const WorldMeshes& worlds,
                         const IndexGrid* grid_asset, const VoxelizeOptions& options, std::vector<std::string>& voxelized);
    void record_imported(vk::CommandRecorder& recorder, const FrameInputs::Volume& in, const IndexGrid& grid_asset);
    void record_index_field(vk::CommandRecorder& recorder, const FrameInputs::Volume& in, bool resident);
    // The voxels the index field is composed over: the whole lattice, or where objects changed.
    passes::VoxelRange recompose_region(const FrameInputs::Volume& in, bool resident) const;
    // The field images' texels spread over the lattice: `outside` where no cluster holds a voxel.
    template <typename T>
    std::vector<T> on_lattice(const std::vector<T>& texels, T outside) const;

    PassKit& kit_;
    passes::GridGeometry lattice_{};
    // Each object's coverage over its box, kept while its world mesh, box and smoothing stay.
    struct ObjectVolume {
        passes::ObjectBox box;
        size_t mesh_hash = 0;  // of the world mesh it was voxelized from
        double smoothing = 0.0;
        uint32_t subsamples = 0;  // the rays a column side it was voxelized with
        vk::Buffer coverage;
    };
    std::map<std::string, ObjectVolume> objects_;
    // The objects and the medium as the index field was last composed of them.
    std::vector<std::pair<std::string, passes::FieldShape>> composed_objects_;
    double composed_medium_ior_ = 0.0;
    float octree_epsilon_ = 0.0f;  // the epsilon of the resident level map
    vk::Buffer grid_values_, pyramid_, levels_;
    vk::Image3D index_field_, coverage_image_;  // at atlas_.dims
    FieldAtlas atlas_;
    vk::Buffer atlas_map_;  // a sparse atlas's map (transport.h)
    std::map<std::string, passes::ObjectBox> boxes_;  // this run's, when it voxelizes
    std::vector<glm::vec4> bending_;
    bool field_fresh_ = false;                          // this run made new field images
    // This run's: the clusters a new layout carries over from the old images, and what its commands
    // read (uploads, scratch), held until they complete.
    struct {
        vk::Image3D index_field, coverage;
        FieldAtlas atlas;
    } carried_;
    std::vector<passes::VoxelizeUploads> uploads_;
    std::vector<vk::Buffer> scratch_;
    vk::Buffer coverage_upload_, zeros_;
    passes::VoxelRange moved_;          // where the objects voxelized now lay before and lie now
    passes::VoxelRange field_changed_;  // where the field images changed since the octree was made
};

}  // namespace refract::scene
