#include "volume/grid_checks.h"

#include <cmath>

namespace refract::volume {

std::string quoted(const std::string& name) {
    // Appended, not concatenated: GCC 12 warns falsely (-Wrestrict) about "'" + name + "'" here.
    std::string out(1, '\'');
    out.append(name).push_back('\'');
    return out;
}

std::string grid_label(const std::string& name, size_t index) {
    if (!name.empty()) return quoted(name);
    std::string out = "#";
    out.append(std::to_string(index)).append(" (unnamed)");
    return out;
}

void check_active_box(const std::array<int64_t, 3>& dim, const std::string& what,
                      const VolumeLimits& limits) {
    // The dimensions multiplied in double: two voxels at opposite ends of the index range overflow 64 bits.
    const double box_voxels = double(dim[0]) * double(dim[1]) * double(dim[2]);
    if (box_voxels > double(limits.max_box_voxels))
        throw VolumeError("the active bounding box of grid " + what + " spans " + std::to_string(dim[0]) +
                          " x " + std::to_string(dim[1]) + " x " + std::to_string(dim[2]) +
                          " voxels, more than the daemon's limit of " +
                          std::to_string(limits.max_box_voxels));
}

void check_grid_value(float value, const std::string& what, const char* where) {
    if (!std::isfinite(value))
        throw VolumeError("grid " + what + " holds a non-finite value (" + std::to_string(value) + ") " +
                          where);
    if (value < 0)
        throw VolumeError("grid " + what + " holds a negative value (" + std::to_string(value) + ") " +
                          where);
}

void require_usable_grid(const VolumeReport& report) {
    for (const GridSummary& grid : report.grids)
        if (grid.usable) return;
    std::string found;
    for (const GridSummary& grid : report.grids)
        found += (found.empty() ? "" : ", ") + quoted(grid.name) + " (" + grid.unusable_reason + ")";
    throw VolumeError("no usable float grid in the file: " + found);
}

}  // namespace refract::volume
