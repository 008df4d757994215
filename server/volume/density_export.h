// A float grid's active voxels as refract-vdb-check exports them for the daemon (vdb_check.h): the
// daemon never runs OpenVDB on an upload, so it reads the values it renders in this small form, whose
// every length it checks, rather than the .vdb file.
//
// The form, little-endian, nothing between the parts:
//   8 bytes   magic "RFXDENS1"
//   u32       leaf count L (at most the reader's max_leaves), u32 0
//   12 x f64  index to world, row-major 3 x 4: world = M (i, j, k, 1), voxel centres at integer (i, j, k)
//   L x       a leaf: 3 x i32 origin (multiples of 8), then 512 x f32 values, z fastest
//             ((x - ox) * 64 + (y - oy) * 8 + (z - oz)): active voxels' values, 0 for inactive ones
// So its size is exactly 112 + L x 2060 bytes. Values are finite and non-negative; origins unique.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace refract::volume {

inline constexpr int kLeafSide = 8;
inline constexpr size_t kLeafVoxels = 512;
inline constexpr size_t kDensityHeaderBytes = 112;
inline constexpr size_t kDensityLeafBytes = 12 + kLeafVoxels * 4;
// The most leaves the daemon takes of one grid: 2^25 voxels (128 MiB of floats), a dense 320^3 box.
inline constexpr uint64_t kMaxDensityLeaves = 65536;

struct DensityLeaf {
    std::array<int32_t, 3> origin{};
    std::array<float, kLeafVoxels> values{};

    bool operator==(const DensityLeaf&) const = default;
};

// One float grid's active voxels (inactive ones read 0) and where they lie.
struct DensityGrid {
    std::array<double, 12> index_to_world{};
    std::vector<DensityLeaf> leaves;

    bool operator==(const DensityGrid&) const = default;
};

// The grid in the form above.
std::string encode_density(const DensityGrid& grid);
// Reads the form above, checking every length and value before it allocates: at most `max_leaves`
// leaves, the size exact, the transform finite and invertible, origins aligned, within 2^28 of 0 and
// unique, values finite and non-negative. Throws VolumeError saying what is wrong.
DensityGrid decode_density(std::string_view bytes, uint64_t max_leaves = kMaxDensityLeaves);

}  // namespace refract::volume
