// Pass 2 (index field): smoothed coverage, a procedural lens or an imported grid -> one rgba32f texel
// per voxel holding n and grad n, plus an rg32f image of coverage (for extinction and scattering) and
// of which object it is.
#pragma once

#include <span>

#include "passes/grid_geometry.h"
#include "passes/mode_pipelines.h"
#include "vk/commands.h"
#include "vk/pipeline.h"
#include "volume_build.h"

namespace refract::passes {

// A box of the lattice's voxels, [first, end).
struct VoxelRange {
    glm::uvec3 first{0u}, end{0u};
    bool empty() const { return glm::any(glm::greaterThanEqual(first, end)); }
    uint64_t count() const {
        return empty() ? 0 : uint64_t{end.x - first.x} * (end.y - first.y) * (end.z - first.z);
    }
};

// What kind of field an object's voxels hold (INDEX_KIND_*), with its parameters.
struct FieldShape {
    uint32_t kind = INDEX_KIND_UNIFORM;
    float n = 1.0f;             // a uniform object's index; a Maxwell fish-eye's n0; unread by the others
    glm::vec4 sphere{0.0f};     // procedural lenses: centre and radius (world)
    bool operator==(const FieldShape&) const = default;
};

// One object's part of the index field: its smoothed coverage over its own box of the scene's lattice.
struct ObjectField {
    FieldShape shape;
    passes::GridGeometry box;     // the lattice's voxels from `offset` on; the coverage's size
    glm::uvec3 offset;           // the box's min corner in the lattice (voxels)
    const vk::Buffer& coverage;  // float per voxel of the box
    uint32_t number;             // 1 + the object's place in name order (the material table's); 0 for the
                                 // one object of a scene of one, whose box is the whole lattice
};

// Where a part of the lattice lies in the field images: its voxels from atlas_first on (the whole
// lattice at the origin when the images are the lattice's; render/field_atlas.h).
struct FieldBlock {
    VoxelRange lattice;
    glm::uvec3 atlas_first{0u};
};

// The most voxels `region` holds in any one block: the medium's coverage the pass reads (`zeros`).
uint64_t largest_part(std::span<const FieldBlock> blocks, VoxelRange region);

class IndexFieldPass {
public:
    explicit IndexFieldPass(vk::Context& context);

    // Records the field of `objects` over `region` of the lattice into the images, where `blocks` store
    // it; the rest keeps what it holds. Returns the images' voxels it wrote (the smallest box holding them).
    // The one object of a scene of one (number 0) writes the whole lattice, its one block. `medium` is the
    // medium's shape (uniform, its index).
    // Several objects' fields join voxel by voxel over the medium (index_field.comp says how), block by
    // block, in the order given; each object's box lies in one block. `zeros` is a float per voxel of
    // the largest part of the region in one block (largest_part), all 0 (the medium's coverage), which
    // resets the region to the medium first; none when the images hold the medium there already.
    // `grid_values` is the imported index grid (the lattice's size) for index_field == grid; any small
    // buffer otherwise.
    VoxelRange record(vk::CommandRecorder& recorder, const FieldShape& medium, const passes::GridGeometry& lattice,
                      std::span<const ObjectField> objects, std::span<const FieldBlock> blocks, VoxelRange region,
                      const vk::Buffer* zeros, const vk::Buffer& grid_values, const vk::Image3D& index_field,
                      const vk::Image3D& coverage_image) const;

private:
    ModePipelines pipelines_;  // by INDEX_KIND_*
};

}  // namespace refract::passes
