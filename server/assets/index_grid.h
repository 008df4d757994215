// An index grid: a refractive index field sampled on a regular grid (from a simulation), uploaded by a
// user. The store keeps and checks it; the renderer samples it.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "protocol/scene_document.h"

namespace refract::scene {

// A refractive index field sampled on a regular grid (from a simulation), covering `bounds` in world space.
struct IndexGrid {
    uint32_t nx = 0, ny = 0, nz = 0;
    protocol::Bounds bounds;
    std::vector<float> n;  // x fastest, then y, then z; every value finite and >= 1
};

// True when the grid's voxels are cubes (their sides agree within 1%): the index field is sampled on
// cubic voxels. Inline: the store checks uploads with it.
inline bool has_cubic_voxels(const IndexGrid& grid) {
    const uint32_t sides[3] = {grid.nx, grid.ny, grid.nz};
    const double h = (grid.bounds.max[0] - grid.bounds.min[0]) / sides[0];
    for (size_t axis = 1; axis < 3; ++axis)
        if (std::abs((grid.bounds.max[axis] - grid.bounds.min[axis]) / sides[axis] - h) > 0.01 * h) return false;
    return true;
}

}  // namespace refract::scene
