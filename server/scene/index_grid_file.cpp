#include "scene/index_grid_file.h"

#include <cstring>

#include "scene/scene_store.h"

namespace refract::scene {
namespace {

constexpr char kGridMagic[8] = {'R', 'F', 'G', 'R', 'I', 'D', '1', '\0'};

}  // namespace

std::vector<char> encode_grid(const IndexGrid& grid) {
    std::vector<char> bytes(sizeof(kGridMagic) + 3 * sizeof(uint32_t) + 6 * sizeof(double) +
                            grid.n.size() * sizeof(float));
    char* out = bytes.data();
    auto put = [&out](const void* data, size_t size) {
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
        throw StoreError(500, "stored index grid is corrupt");
    const char* in = bytes.data() + sizeof(kGridMagic);
    auto get = [&in](void* data, size_t size) {
        std::memcpy(data, in, size);
        in += size;
    };
    get(&grid.nx, sizeof(uint32_t));
    get(&grid.ny, sizeof(uint32_t));
    get(&grid.nz, sizeof(uint32_t));
    get(grid.bounds.min.data(), 3 * sizeof(double));
    get(grid.bounds.max.data(), 3 * sizeof(double));
    size_t count = size_t{grid.nx} * grid.ny * grid.nz;
    if (bytes.size() != header + count * sizeof(float))
        throw StoreError(500, "stored index grid is truncated");
    grid.n.resize(count);
    get(grid.n.data(), count * sizeof(float));
    validate_index_grid(grid);
    return grid;
}

}  // namespace refract::scene
