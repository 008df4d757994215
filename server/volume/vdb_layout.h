// The parts of an OpenVDB file that declare their own lengths, walked before OpenVDB reads anything:
// OpenVDB allocates and fills every string and metadata value at the length the file declares (up to
// 4 GiB) before it reads a byte of it.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace refract::volume {

// The file as one single-grid stream per grid, each holding the header, the file's metadata, the grid's
// descriptor and the grid's bytes, with every length declared before each grid's tree checked against
// the bytes present. Only these are handed to OpenVDB: past a grid's transform it reads no length it
// allocates before reading. A file of several grids must have their offsets (written by io::File, as
// every DCC does); an instanced grid is refused. Throws VolumeError.
std::vector<std::string> split_grids(std::string_view bytes, uint32_t max_grids);

}  // namespace refract::volume
