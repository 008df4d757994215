// Volume assets as NanoVDB files (.nvdb), read without NanoVDB's own reader: it allocates what a file's
// headers declare and follows the offsets in a grid's tree unchecked, so every size, count and offset is
// checked here against the bytes present before anything is read through it. inspect_vdb and
// export_density (vdb_reader.h) hand a file starting with NanoVDB's magic number to these.
//
// The format read (NanoVDB 32.0 to 32.4, as OpenVDB 10's nanovdb::io::writeGrids writes it, uncompressed):
// segments, each a 16-byte header (magic "NanoVDB0", version, grid count, codec), then per grid a
// 176-byte description and its name, then the grids' buffers; a buffer is NanoVDB's in-memory grid, a
// 672-byte GridData, a 64-byte TreeData giving the offsets and counts of the leaf, lower and upper node
// arrays and of the root, then those nodes.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "volume/vdb_reader.h"

namespace refract::volume {

// Whether `bytes` start as a NanoVDB file does ("NanoVDB" and a digit, any format generation, or the
// first's magic byte-swapped: a big-endian file, refused as such).
bool is_nanovdb(std::string_view bytes);

// The grids of the NanoVDB file in `bytes`, in file order, checked as inspect_vdb checks a .vdb's: the
// report is the one the same grids give in a .vdb (float grids usable, tiles counted by the voxels they
// cover). Refused with VolumeError: another magic or version, a compressed codec (ZIP, BLOSC), more
// than max_grids grids, a declared size or a node offset or count beyond the bytes present, a tree that
// reaches a node twice or not every node it lists, a non-linear or singular map, a float grid with a
// non-finite or negative active value or background, or an active box beyond max_box_voxels.
std::vector<GridSummary> inspect_nvdb(std::string_view bytes, const VolumeLimits& limits);

// The float grid `grid` of the NanoVDB file in `bytes`, checked as inspect_nvdb checks it, its active
// tiles made voxels: the export export_density gives for the same grid in a .vdb. At most max_leaves
// leaves, counted before any is allocated. Throws VolumeError.
DensityGrid export_nvdb_density(std::string_view bytes, const std::string& grid, const VolumeLimits& limits,
                                uint64_t max_leaves);

}  // namespace refract::volume
