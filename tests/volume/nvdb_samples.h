// NanoVDB files for the volume tests, made from the OpenVDB samples (vdb_samples.h) as a user makes them:
// each grid converted with nanovdb::openToNanoVDB and written with nanovdb::io::writeGrids.
#pragma once

#include <cstdint>
#include <string>

#include "volume/vdb_reader.h"

namespace refract::test {

// The grids of the .vdb file `vdb`, in its order, as the bytes of one uncompressed .nvdb file.
std::string nvdb_from_vdb(const std::string& vdb);

// Where the layout of an uncompressed .nvdb file of one segment puts grid `index`'s buffer (its
// GridData), found through the grids' descriptions; the file must hold that many grids.
uint64_t nvdb_grid_offset(const std::string& nvdb, uint32_t index);

// The reason inspect_vdb refuses `bytes` with (a .vdb or a .nvdb), or "(accepted)".
std::string volume_refusal(const std::string& bytes, const volume::VolumeLimits& limits = {});

}  // namespace refract::test
