// Fuzzes the NanoVDB reader (volume/nvdb_reader.h) through inspect_vdb and export_density, as an upload
// reaches it. A valid .nvdb is larger than the fuzzer's inputs (an upper node alone is 264 KiB), so an
// input is either a file of its own (first byte odd: the rest is the file) or edits to a valid one built
// here with NanoVDB's GridBuilder (first byte even: then records of 4 bytes, a 16-bit offset, a byte, and
// a byte that sends the offset into the headers and root, or, when odd, anywhere in the file).
// Invariants: only VolumeError is thrown; a grid read is exported within its limits with finite
// non-negative values at unique, aligned origins.
#include <nanovdb/util/GridBuilder.h>
#include <nanovdb/util/IO.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <set>
#include <sstream>
#include <string>
#include <string_view>

#include "fuzz_check.h"
#include "volume/vdb_reader.h"

using namespace refract::volume;

namespace {

// A float grid "density" of voxels in two leaves (one lower and one upper node), voxel size 0.1.
std::string valid_nvdb() {
    nanovdb::GridBuilder<float> builder(0.0f, nanovdb::GridClass::FogVolume);
    auto access = builder.getAccessor();
    for (int x = -3; x < 5; ++x)
        for (int y = 0; y < 3; ++y) access.setValue(nanovdb::Coord(x, y, 2), 0.25f + 0.125f * float(x + 3));
    const auto handle = builder.getHandle<>(0.1, nanovdb::Vec3d(0), "density");
    nanovdb::io::Segment segment;
    segment.add(handle);
    segment.meta[0].fileSize = handle.size();
    std::ostringstream out(std::ios::binary);
    segment.write(out);
    out.write(reinterpret_cast<const char*>(handle.data()), static_cast<std::streamsize>(handle.size()));
    return out.str();
}

// The header, the grid's description and name, GridData, TreeData, the root and a few root tiles.
constexpr size_t kHeaderRegion = 16 + 176 + 8 + 672 + 64 + 64 + 4 * 32;

void check(std::string_view bytes) {
    const VolumeLimits limits{.max_box_voxels = uint64_t{1} << 21, .max_grids = 4};
    VolumeReport report;
    try {
        report = inspect_vdb(bytes, limits);
    } catch (const VolumeError&) {
        return;
    }
    for (const GridSummary& grid : report.grids) {
        if (!grid.usable) continue;
        DensityGrid exported;
        try {
            exported = export_density(bytes, grid.name, limits, 64);
        } catch (const VolumeError&) {
            continue;
        }
        REFRACT_FUZZ_CHECK(exported.leaves.size() <= 64);
        std::set<std::array<int32_t, 3>> origins;
        for (const DensityLeaf& leaf : exported.leaves) {
            REFRACT_FUZZ_CHECK(origins.insert(leaf.origin).second);
            for (int32_t coordinate : leaf.origin) REFRACT_FUZZ_CHECK(coordinate % kLeafSide == 0);
            for (float value : leaf.values) REFRACT_FUZZ_CHECK(std::isfinite(value) && value >= 0.0f);
        }
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0) return 0;
    if (data[0] & 1) {
        check(std::string_view(reinterpret_cast<const char*>(data + 1), size - 1));
        return 0;
    }
    static const std::string valid = valid_nvdb();
    std::string bytes = valid;
    for (size_t at = 1; at + 4 <= size; at += 4) {
        const size_t offset = size_t(data[at]) | size_t(data[at + 1]) << 8;
        const size_t where = data[at + 3] & 1 ? (offset | size_t(data[at + 3] >> 1) << 16) % bytes.size()
                                              : offset % std::min(kHeaderRegion, bytes.size());
        bytes[where] = static_cast<char>(data[at + 2]);
    }
    check(bytes);
    return 0;
}
