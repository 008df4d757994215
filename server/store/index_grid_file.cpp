#include "store/index_grid_file.h"

#include <cstring>
#include <initializer_list>

#include "store/store.h"

namespace refract::scene {
namespace {

constexpr char kGridMagic[8] = {'R', 'F', 'G', 'R', 'I', 'D', '1', '\0'};

}  // namespace

std::vector<char> encode_grid(const IndexGrid& grid) {
    std::vector<char> bytes(sizeof(kGridMagic) + 3 * sizeof(uint32_t) + 6 * sizeof(double) +
                            grid.n.size() * sizeof(float));
    char* out = bytes.data();
    auto put = [&out](const void* data, size_t size) {
        if (size == 0) return;  // no values: data may be null
        std::memcpy(out, data, size);
        out += size;
    };
    put(kGridMagic, sizeof(kGridMagic));
    put(&grid.nx, sizeof(uint32_t));
    put(&grid.ny, sizeof(uint32_t));
    put(&grid.nz, sizeof(uint32_t));
    put(grid.bounds.min.data(), 3 * sizeof(double));
    put(grid.bounds.max.data(), 3 * sizeof(double));
    put(grid.n.data(), grid.n.size() * sizeof(float));
    return bytes;
}

IndexGrid decode_grid(const std::string& bytes) {
    IndexGrid grid;
    size_t header = sizeof(kGridMagic) + 3 * sizeof(uint32_t) + 6 * sizeof(double);
    if (bytes.size() < header || std::memcmp(bytes.data(), kGridMagic, sizeof(kGridMagic)) != 0)
        throw StoreError(StoreFailure::broken, "stored index grid is corrupt");
    const char* in = bytes.data() + sizeof(kGridMagic);
    auto get = [&in](void* data, size_t size) {
        if (size == 0) return;  // a grid side of 0 (refused below): data is null
        std::memcpy(data, in, size);
        in += size;
    };
    get(&grid.nx, sizeof(uint32_t));
    get(&grid.ny, sizeof(uint32_t));
    get(&grid.nz, sizeof(uint32_t));
    get(grid.bounds.min.data(), 3 * sizeof(double));
    get(grid.bounds.max.data(), 3 * sizeof(double));
    // nx*ny*nz in 64 bits can wrap (three 32-bit sides), and count*4 more easily: a header claiming 2^31 by
    // 2^31 by 1 would match a file of no values and ask for 16 EiB. Compare the sides with what is there.
    const size_t values = (bytes.size() - header) / sizeof(float);
    size_t count = 1;
    for (const uint32_t side : {grid.nx, grid.ny, grid.nz}) {
        if (side != 0 && count > values / side)
            throw StoreError(StoreFailure::broken, "stored index grid is truncated");
        count *= side;
    }
    if (bytes.size() != header + count * sizeof(float))
        throw StoreError(StoreFailure::broken, "stored index grid is truncated");
    grid.n.resize(count);
    get(grid.n.data(), count * sizeof(float));
    validate_index_grid(grid);
    return grid;
}

}  // namespace refract::scene
