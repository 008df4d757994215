// Fuzzes the index grid: the stored file's decoder (scene::decode_grid), and the check an uploaded grid
// goes through (scene::validate_index_grid). Input starting with the file's magic tag is decoded as a
// file; any other input is read as an upload, laid out like the file after its tag (nx, ny, nz, the
// bounds, the values). Invariants: only StoreError is thrown (broken for a broken file, invalid for an
// invalid grid); a grid that is accepted encodes to exactly the bytes it was decoded from, and decodes back.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_check.h"
#include "store/index_grid_file.h"
#include "store/store.h"

using namespace refract::scene;

namespace {

constexpr char kMagic[8] = {'R', 'F', 'G', 'R', 'I', 'D', '1', '\0'};
constexpr size_t kHeader = 3 * sizeof(uint32_t) + 6 * sizeof(double);

void check_encodes_back(const IndexGrid& grid, const std::string& file) {
    const std::vector<char> bytes = encode_grid(grid);
    REFRACT_FUZZ_CHECK(std::string(bytes.begin(), bytes.end()) == file);
    const IndexGrid again = decode_grid(file);
    REFRACT_FUZZ_CHECK(again.nx == grid.nx && again.ny == grid.ny && again.nz == grid.nz);
    REFRACT_FUZZ_CHECK(again.bounds == grid.bounds);
    REFRACT_FUZZ_CHECK(again.n.size() == grid.n.size());
    REFRACT_FUZZ_CHECK(grid.n.empty() ||
                       std::memcmp(again.n.data(), grid.n.data(), grid.n.size() * sizeof(float)) == 0);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string input(reinterpret_cast<const char*>(data), size);
    if (input.size() >= sizeof kMagic && std::memcmp(input.data(), kMagic, sizeof kMagic) == 0) {
        IndexGrid grid;
        try {
            grid = decode_grid(input);
        } catch (const StoreError& e) {
            REFRACT_FUZZ_CHECK(e.failure() == StoreFailure::broken || e.failure() == StoreFailure::invalid);
            return 0;
        }
        check_encodes_back(grid, input);
        return 0;
    }

    // An upload: the sides and bounds from the query, the body's values (whole floats only).
    if (input.size() < kHeader) return 0;
    IndexGrid grid;
    const char* in = input.data();
    std::memcpy(&grid.nx, in, sizeof(uint32_t));
    std::memcpy(&grid.ny, in + 4, sizeof(uint32_t));
    std::memcpy(&grid.nz, in + 8, sizeof(uint32_t));
    std::memcpy(grid.bounds.min.data(), in + 12, 3 * sizeof(double));
    std::memcpy(grid.bounds.max.data(), in + 36, 3 * sizeof(double));
    grid.n.resize((input.size() - kHeader) / sizeof(float));
    if (!grid.n.empty()) std::memcpy(grid.n.data(), in + kHeader, grid.n.size() * sizeof(float));
    try {
        validate_index_grid(grid);
    } catch (const StoreError& e) {
        REFRACT_FUZZ_CHECK(e.failure() == StoreFailure::invalid);
        return 0;
    }
    const std::vector<char> bytes = encode_grid(grid);
    check_encodes_back(grid, std::string(bytes.begin(), bytes.end()));
    return 0;
}
