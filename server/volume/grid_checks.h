// The checks a volume grid passes whichever file format holds it (vdb_reader.cpp, nvdb_reader.cpp), so
// that the same grid is refused with the same words in a .vdb and in a .nvdb.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "volume/vdb_reader.h"

namespace refract::volume {

std::string quoted(const std::string& name);
// A grid's name in a message: 'name', or "#index (unnamed)".
std::string grid_label(const std::string& name, size_t index);
// Refuses an active bounding box of `dim` voxels (each at least 1) beyond limits.max_box_voxels.
void check_active_box(const std::array<int64_t, 3>& dim, const std::string& what, const VolumeLimits& limits);
// Refuses a value that is not finite or is negative (it would make extinction negative, or poison every
// estimate through it); `where` says where it lies ("in an active voxel", "as its background").
void check_grid_value(float value, const std::string& what, const char* where);
// Refuses a report without a usable grid, listing what each grid is instead.
void require_usable_grid(const VolumeReport& report);

}  // namespace refract::volume
