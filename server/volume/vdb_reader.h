// Volume assets (smoke, clouds, fire) as OpenVDB files (or NanoVDB ones, nvdb_reader.h): read from the
// uploaded bytes, checked whole, and summarised per grid. Nothing here renders; a volume's grids are
// named by the document later.
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "volume/density_export.h"

namespace refract::volume {

// Why a volume file was refused, in words a user can act on.
class VolumeError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What one file may hold.
struct VolumeLimits {
    uint64_t max_box_voxels = uint64_t{512} * 512 * 512;
    uint32_t max_grids = 64;
};

// The limits under a daemon's --max-resolution: no grid's active bounding box may hold more voxels than
// the densest field it renders (max_resolution cubed).
VolumeLimits limits_for_resolution(uint32_t max_resolution);

// One grid of a file, as GET /api/volumes lists it.
struct GridSummary {
    std::string name;
    std::string type;             // OpenVDB's value type name: "float", "vec3s", ...
    bool usable = false;          // a float grid (OpenVDB's 5-4-3 tree) with active voxels
    std::string unusable_reason;  // why not, when !usable
    uint64_t active_voxels = 0;   // active voxels, tiles counted by the voxels they cover
    std::array<int32_t, 3> index_min{}, index_max{};  // active bounding box, inclusive, in index space
    std::array<double, 3> world_min{}, world_max{};   // the same box's corners through the grid's transform
    std::array<double, 3> voxel_size{};

    bool operator==(const GridSummary&) const = default;
};

struct VolumeReport {
    std::vector<GridSummary> grids;  // in file order

    bool operator==(const VolumeReport&) const = default;
};

// Reads an OpenVDB file from `bytes` and checks it: a VDB file of format 222 to 224 (truncated or other
// bytes are refused with the reason; a NanoVDB file goes to inspect_nvdb, nvdb_reader.h, and reports as
// the same grids in a .vdb would) whose declared lengths fit (vdb_layout.h), at most
// max_grids grids, at least one usable float grid, each float grid with
// OpenVDB's standard 5-4-3 tree, a linear transform with a finite positive voxel size, an active bounding
// box within max_box_voxels and finite non-negative values (active and background). Grids of other
// value types are listed as unusable. Throws VolumeError naming the grid at fault.
// It runs in the calling process, whose memory keeps what OpenVDB does not free of a refused file (the
// nodes of a tree whose topology ends early): a long-lived process checks uploads apart (vdb_check.h).
VolumeReport inspect_vdb(std::string_view bytes, const VolumeLimits& limits);

// The float grid `grid` of the file in `bytes`, checked as inspect_vdb checks it, with its active tiles
// made voxels: at most max_leaves leaves of 8^3. Throws VolumeError (no such float grid, too many
// leaves, or what inspect_vdb refuses). Runs OpenVDB in the calling process, as inspect_vdb does: the
// daemon calls export_density_apart (vdb_check.h).
DensityGrid export_density(std::string_view bytes, const std::string& grid, const VolumeLimits& limits,
                           uint64_t max_leaves = kMaxDensityLeaves);

// A report as JSON (the API's and the stores' form) and back.
nlohmann::json to_json(const VolumeReport& report);
VolumeReport volume_report_from_json(const nlohmann::json& j);

}  // namespace refract::volume
