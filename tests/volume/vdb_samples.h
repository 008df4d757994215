// OpenVDB files written by OpenVDB itself, for the volume tests (no VDB sample files ship with Debian),
// through io::File as DCCs write them unless said otherwise.
#pragma once

#include <array>
#include <cstddef>
#include <string>

#include "volume/density_export.h"

namespace refract::test {

// A density sphere of `radius` voxels (1 at the centre, falling linearly to 0 at the edge), voxel size
// 0.1, as the bytes of a .vdb file, with a vec3s grid "vel" beside it when `with_velocity`.
std::string density_sphere_vdb(int radius, bool with_velocity = false);
// A float grid "density" written by io::Stream (no grid offsets), with an empty vec3s grid "vel" after
// it when `with_velocity`.
std::string as_stream_vdb(bool with_velocity);
// A float grid whose string metadata "comment" declares 2^32 - 1 bytes, of which 4 are present.
std::string metadata_bomb_vdb();
// A file holding only a vec3s grid named "vel".
std::string vector_only_vdb();
// A float grid "density" of a few voxels, one of them `bad` (NaN, infinite or negative).
std::string density_with_value_vdb(float bad);
// A float grid "density" with two active voxels `apart` voxels apart on each axis.
std::string far_apart_vdb(int apart);
// A float grid named `name` over the inclusive index box [lo, hi], voxel size `voxel` (index (i, j, k) at
// world (i, j, k) x voxel), whose value is a + b x i: a linear ramp along x. With b = 0 the box is filled
// with active tiles where whole nodes fit (as DCCs write constant regions), else voxel by voxel.
std::string ramp_box_vdb(const std::array<int, 3>& lo, const std::array<int, 3>& hi, double voxel, float a, float b,
                         const std::string& name = "density");
// A flame: the density sphere of density_sphere_vdb(radius) and, over the same voxels, a float grid
// "temperature" of `kelvin` at the centre falling linearly to 0 at the edge, and a float grid "heat" of
// the density's values.
std::string flame_vdb(int radius, float kelvin);
// A float grid `name` holding `grid`'s leaves' non-zero values as active voxels, with its linear transform.
std::string vdb_of(const volume::DensityGrid& grid, const std::string& name);
// A float grid with a 6-5-4-3 tree (deeper than OpenVDB's standard), registered only while writing.
std::string deep_tree_vdb();

}  // namespace refract::test
