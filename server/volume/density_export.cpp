#include "volume/density_export.h"

#include <cmath>
#include <cstring>
#include <set>

#include "volume/vdb_reader.h"

namespace refract::volume {

namespace {

constexpr char kMagic[8] = {'R', 'F', 'X', 'D', 'E', 'N', 'S', '1'};
// Origins stay this close to 0, so that origin + 8 and the transform's products never overflow.
constexpr int32_t kMaxOrigin = int32_t{1} << 28;
// Transform entries are bounded so that a world point of a voxel within kMaxOrigin stays finite.
constexpr double kMaxTransformEntry = 1e6;

template <typename T>
void put(std::string& out, const T& value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out.append(bytes, sizeof(T));
}

template <typename T>
T take(std::string_view bytes, size_t& at) {
    T value;
    std::memcpy(&value, bytes.data() + at, sizeof(T));
    at += sizeof(T);
    return value;
}

}  // namespace

std::string encode_density(const DensityGrid& grid) {
    std::string out;
    out.reserve(kDensityHeaderBytes + grid.leaves.size() * kDensityLeafBytes);
    out.append(kMagic, sizeof kMagic);
    put(out, static_cast<uint32_t>(grid.leaves.size()));
    put(out, uint32_t{0});
    for (double entry : grid.index_to_world) put(out, entry);
    for (const DensityLeaf& leaf : grid.leaves) {
        for (int32_t coordinate : leaf.origin) put(out, coordinate);
        out.append(reinterpret_cast<const char*>(leaf.values.data()), kLeafVoxels * sizeof(float));
    }
    return out;
}

DensityGrid decode_density(std::string_view bytes, uint64_t max_leaves) {
    if (bytes.size() < kDensityHeaderBytes)
        throw VolumeError("density export: " + std::to_string(bytes.size()) + " bytes, shorter than its header");
    if (std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
        throw VolumeError("density export: not one (wrong magic number)");
    size_t at = sizeof kMagic;
    const auto count = take<uint32_t>(bytes, at);
    if (take<uint32_t>(bytes, at) != 0) throw VolumeError("density export: a reserved word is not 0");
    if (count > max_leaves)
        throw VolumeError("density export: " + std::to_string(count) + " leaves, more than the limit of " +
                          std::to_string(max_leaves) + " (a grid of over " + std::to_string(max_leaves * kLeafVoxels) +
                          " active voxels)");
    // Counted in 64 bits before anything is allocated: count * 2060 fits easily.
    const uint64_t expected = kDensityHeaderBytes + uint64_t{count} * kDensityLeafBytes;
    if (bytes.size() != expected)
        throw VolumeError("density export: " + std::to_string(bytes.size()) + " bytes where " + std::to_string(count) +
                          " leaves take " + std::to_string(expected));
    DensityGrid grid;
    for (double& entry : grid.index_to_world) {
        entry = take<double>(bytes, at);
        if (!std::isfinite(entry) || std::abs(entry) > kMaxTransformEntry)
            throw VolumeError("density export: a transform entry is not finite or beyond 1e6");
    }
    const auto& m = grid.index_to_world;
    const double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
                       m[2] * (m[4] * m[9] - m[5] * m[8]);
    if (!(std::abs(det) > 1e-30)) throw VolumeError("density export: the transform is not invertible");
    grid.leaves.resize(count);
    std::set<std::array<int32_t, 3>> origins;
    for (DensityLeaf& leaf : grid.leaves) {
        for (int32_t& coordinate : leaf.origin) {
            coordinate = take<int32_t>(bytes, at);
            if (coordinate % kLeafSide != 0 || coordinate < -kMaxOrigin || coordinate > kMaxOrigin)
                throw VolumeError("density export: a leaf origin is not a multiple of 8 within 2^28 of 0");
        }
        if (!origins.insert(leaf.origin).second) throw VolumeError("density export: two leaves at one origin");
        std::memcpy(leaf.values.data(), bytes.data() + at, kLeafVoxels * sizeof(float));
        at += kLeafVoxels * sizeof(float);
        for (float value : leaf.values)
            if (!std::isfinite(value) || value < 0.0f)
                throw VolumeError("density export: a value that is not finite and non-negative");
    }
    return grid;
}

}  // namespace refract::volume
