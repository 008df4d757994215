// The stored form of an imported index grid (data dir grids/ID.grid): a magic tag, the three sides, the
// bounds and the values, in host byte order.
#pragma once

#include <string>
#include <vector>

#include "assets/index_grid.h"

namespace refract::scene {

// The file's bytes for a grid that passed validate_index_grid().
std::vector<char> encode_grid(const IndexGrid& grid);

// Reads a grid file back. Throws StoreError(broken) when the bytes are not a whole grid file, and what
// validate_index_grid() throws when the grid they hold is not valid.
IndexGrid decode_grid(const std::string& bytes);

}  // namespace refract::scene
