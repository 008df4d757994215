// Volume assets as NanoVDB files (volume/nvdb_reader.h): an OpenVDB sample converted with
// nanovdb::openToNanoVDB reads as the .vdb it came from (the same report, the same export), and every
// hostile change to one is refused with its reason, never read past its bytes.
#include "volume/nvdb_reader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>

#include "volume/nvdb_samples.h"
#include "volume/vdb_check.h"
#include "volume/vdb_reader.h"
#include "volume/vdb_samples.h"

namespace refract::volume {
namespace {

using test::nvdb_from_vdb;

// Byte offsets of the layout (nanovdb/util/IO.h, NanoVDB.h 32.4) that the hostile files change.
constexpr size_t kHeaderVersion = 8, kHeaderCodec = 14, kMetaGridSize = 16, kMetaFileSize = 24,
                 kMetaCodec = 16 + 168;
constexpr size_t kGridVersion = 16, kGridSize = 32, kGridMatrix = 296 + 88, kTree = 672,
                 kTreeCounts = 672 + 32;

std::string refusal(const std::string& bytes, const VolumeLimits& limits = {}) {
    return test::volume_refusal(bytes, limits);
}

template <typename T>
std::string with(std::string bytes, size_t at, T value) {
    std::memcpy(bytes.data() + at, &value, sizeof value);
    return bytes;
}

template <typename T>
T read(const std::string& bytes, size_t at) {
    T value;
    std::memcpy(&value, bytes.data() + at, sizeof value);
    return value;
}

std::map<std::array<int32_t, 3>, DensityLeaf> by_origin(const DensityGrid& grid) {
    std::map<std::array<int32_t, 3>, DensityLeaf> leaves;
    for (const DensityLeaf& leaf : grid.leaves) EXPECT_TRUE(leaves.emplace(leaf.origin, leaf).second);
    return leaves;
}

// OpenVDB's samples, voxels and tiles of both internal levels among them, each with several float grids.
std::vector<std::string> vdb_samples() {
    return {test::density_sphere_vdb(8),
            test::density_sphere_vdb(4, true),
            test::ramp_box_vdb({-16, -16, -16}, {23, 23, 23}, 0.05, 2.0f, 0.0f),  // lower-node tiles
            test::ramp_box_vdb({0, -128, 0}, {255, 127, 127}, 0.25, 0.5f, 0.0f),  // upper-node tiles
            test::ramp_box_vdb({-2, 0, 2}, {20, 5, 9}, 0.5, 0.25f, 0.125f),
            test::flame_vdb(5, 1500.0f),
            test::far_apart_vdb(300)};
}

TEST(NvdbReader, ReportsAndExportsAsTheVdbItWasConvertedFrom) {
    for (const std::string& vdb : vdb_samples()) {
        const std::string nvdb = nvdb_from_vdb(vdb);
        ASSERT_TRUE(is_nanovdb(nvdb));
        const VolumeReport report = inspect_vdb(nvdb, {});
        EXPECT_EQ(report, inspect_vdb(vdb, {})) << to_json(report).dump();
        for (const GridSummary& grid : report.grids) {
            if (!grid.usable) continue;
            const DensityGrid from_nvdb = export_density(nvdb, grid.name, {});
            const DensityGrid from_vdb = export_density(vdb, grid.name, {});
            for (size_t i = 0; i < 12; ++i)
                EXPECT_NEAR(from_nvdb.index_to_world[i], from_vdb.index_to_world[i], 1e-12)
                    << grid.name << " " << i;
            EXPECT_EQ(by_origin(from_nvdb), by_origin(from_vdb)) << grid.name;
            EXPECT_EQ(decode_density(encode_density(from_nvdb)), from_nvdb);
        }
    }
}

// The samples above hold tiles of both internal levels (NanoVDB's TreeData counts them): made voxels.
TEST(NvdbReader, TheSamplesHoldTilesOfBothInternalLevels) {
    const std::vector<std::string> samples = vdb_samples();
    for (size_t sample : {size_t{2}, size_t{3}}) {
        const std::string nvdb = nvdb_from_vdb(samples[sample]);
        const size_t tree = test::nvdb_grid_offset(nvdb, 0) + kTree;
        EXPECT_GT(read<uint32_t>(nvdb, tree + 44 + 4 * (sample - 2)), 0u) << sample;  // mTileCount[level]
        EXPECT_EQ(read<uint32_t>(nvdb, tree + 32), 0u) << sample;                     // no leaves: tiles only
    }
    EXPECT_EQ(export_density(nvdb_from_vdb(samples[3]), "density", {}).leaves.size(), 4u * 16 * 16 * 16);
}

TEST(NvdbReader, ListsOtherGridTypesAndRefusesAFileWithoutAFloatGrid) {
    const VolumeReport report = inspect_vdb(nvdb_from_vdb(test::density_sphere_vdb(4, true)), {});
    ASSERT_EQ(report.grids.size(), 2u);
    EXPECT_EQ(report.grids[1].type, "vec3s");
    EXPECT_EQ(report.grids[1].unusable_reason, "a vec3s grid; only float grids are read");
    const std::string why = refusal(nvdb_from_vdb(test::vector_only_vdb()));
    EXPECT_NE(why.find("no usable float grid in the file: 'vel' (a vec3s grid"), std::string::npos) << why;
    try {
        export_density(nvdb_from_vdb(test::density_sphere_vdb(4, true)), "vel", {});
        ADD_FAILURE() << "exported a vector grid";
    } catch (const VolumeError& e) {
        EXPECT_STREQ(e.what(), "no float grid named 'vel' in the file");
    }
}

TEST(NvdbReader, RefusesValuesBoxesGridsAndLeavesBeyondWhatIsRead) {
    for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
        const std::string why = refusal(nvdb_from_vdb(test::density_with_value_vdb(bad)));
        EXPECT_NE(why.find("grid 'density' holds a non-finite value"), std::string::npos) << why;
    }
    std::string why = refusal(nvdb_from_vdb(test::density_with_value_vdb(-0.25f)));
    EXPECT_NE(why.find("grid 'density' holds a negative value (-0.250000) in an active voxel"),
              std::string::npos)
        << why;
    why = refusal(nvdb_from_vdb(test::far_apart_vdb(1'000'000)));
    EXPECT_NE(why.find("active bounding box of grid 'density' spans 1000001 x 1000001 x 1000001"),
              std::string::npos)
        << why;
    const std::string nine = nvdb_from_vdb(test::far_apart_vdb(8));
    EXPECT_NO_THROW(inspect_vdb(nine, {.max_box_voxels = 729}));
    EXPECT_NE(refusal(nine, {.max_box_voxels = 728}).find("limit of 728"), std::string::npos);
    why = refusal(nvdb_from_vdb(test::density_sphere_vdb(2, true)), {.max_grids = 1});
    EXPECT_NE(why.find("holds 2 grids, more than the limit of 1"), std::string::npos) << why;
    try {
        export_density(nvdb_from_vdb(test::density_sphere_vdb(6)), "density", {}, 7);
        ADD_FAILURE() << "exported past max_leaves";
    } catch (const VolumeError& e) {
        EXPECT_NE(std::string(e.what()).find("8 leaves of 8^3 voxels, more than the 7 a scene takes"),
                  std::string::npos)
            << e.what();
    }
}

// A NanoVDB background is read too: NaN there poisons every lookup outside the active voxels.
TEST(NvdbReader, RefusesABadBackground) {
    const std::string nvdb = nvdb_from_vdb(test::density_sphere_vdb(3));
    const size_t grid = test::nvdb_grid_offset(nvdb, 0);
    const size_t root = grid + kTree + read<uint64_t>(nvdb, grid + kTree + 24);
    const std::string why = refusal(with(nvdb, root + 28, -1.0f));
    EXPECT_NE(why.find("grid 'density' holds a negative value (-1.000000) as its background"),
              std::string::npos)
        << why;
}

TEST(NvdbReader, RefusesEveryTruncation) {
    const std::string nvdb = nvdb_from_vdb(test::density_sphere_vdb(6, true));
    for (size_t length = 0; length < nvdb.size(); length += std::max<size_t>(1, nvdb.size() / 211)) {
        const std::string why = refusal(nvdb.substr(0, length));
        if (length < 8)
            EXPECT_NE(why.find("not an OpenVDB file"), std::string::npos) << length << ": " << why;
        else
            EXPECT_NE(why.find("not a readable NanoVDB file: it ends inside"), std::string::npos)
                << length << ": " << why;
    }
    for (size_t cut : {size_t{15}, size_t{17}, size_t{16 + 176}, nvdb.size() - 1})
        EXPECT_NE(refusal(nvdb.substr(0, cut)).find("it ends inside"), std::string::npos) << cut;
    EXPECT_NE(refusal(nvdb + "junk").find("ends inside a segment header"), std::string::npos);
}

// Each header field broken in turn, refused with its reason before anything is read through it.
TEST(NvdbReader, RefusesHostileHeadersWithTheReason) {
    const std::string nvdb = nvdb_from_vdb(test::density_sphere_vdb(6));
    const size_t grid = test::nvdb_grid_offset(nvdb, 0);
    const uint32_t version = read<uint32_t>(nvdb, kHeaderVersion);
    const size_t tile0 = grid + kTree + read<uint64_t>(nvdb, grid + kTree + 24) + 64;
    const struct {
        std::string bytes;
        const char* reason;
    } hostile[] = {
        {"NanoVDB2" + nvdb.substr(8), "magic number NanoVDB2 is of another NanoVDB generation"},
        {with(nvdb, 0, __builtin_bswap64(read<uint64_t>(nvdb, 0))), "a big-endian NanoVDB file"},
        {with(nvdb, kHeaderVersion, (31u << 21) | version % (1u << 21)), "a segment is of NanoVDB 31."},
        {with(nvdb, kHeaderVersion, version + (40u << 10)), "outside what this build reads (32.0 to 32.4)"},
        {with(nvdb, grid + kGridVersion, 33u << 21), "grid 'density' is of NanoVDB 33.0.0"},
        {with(nvdb, kHeaderCodec, uint16_t{1}), "a compressed NanoVDB file (a segment uses ZIP)"},
        {with(nvdb, kHeaderCodec, uint16_t{2}), "a compressed NanoVDB file (a segment uses BLOSC)"},
        {with(nvdb, kMetaCodec, uint16_t{2}), "(grid 'density' uses BLOSC)"},
        {with(nvdb, 12, uint16_t{0}), "a segment of no grids"},
        {with(nvdb, 12, uint16_t{65535}), "holds 65535 grids, more than the limit of 64"},
        {with(with(nvdb, kMetaGridSize, uint64_t{1} << 40), kMetaFileSize, uint64_t{1} << 40),
         "it ends inside grid 'density' (1099511627776 bytes declared"},
        {with(nvdb, kMetaFileSize, uint64_t{100}), "stored in another size than its own"},
        {with(nvdb, 16 + 136, uint32_t{0xffffffff}), "ends inside a grid's name (4294967295 bytes declared"},
        {with(nvdb, grid, uint64_t{0}), "does not start with NanoVDB's magic number"},
        {with(nvdb, grid + kGridSize, uint64_t{1} << 40),
         "declares 1099511627776 bytes where the file holds"},
        {with(nvdb, grid + kGridMatrix, std::numeric_limits<double>::quiet_NaN()),
         "transform that is not finite"},
        {with(nvdb, grid + kGridMatrix, 0.0), "voxel size that is not finite and positive"},
        {with(with(nvdb, grid + kGridMatrix + 8, 0.1), grid + kGridMatrix + 32, 0.0),
         "transform that is not invertible"},
        {with(nvdb, grid + kTree, uint64_t{1} << 40),
         "lists 8 leaves at byte 1099511627776 of its tree, beyond"},
        {with(nvdb, grid + kTreeCounts, uint32_t{0xffffffff}), "lists 4294967295 leaves"},
        {with(nvdb, grid + kTreeCounts + 4, uint32_t{100}), "lists 100 lower internal nodes"},
        {with(nvdb, grid + kTreeCounts + 8, uint32_t{200}), "lists 200 upper internal nodes"},
        {with(nvdb, grid + kTreeCounts + 8, uint32_t{9}), "lists nodes its tree does not reach"},
        {with(nvdb, grid + kTreeCounts + 8, uint32_t{0}), "does not lead to an upper internal node"},
        {with(nvdb, grid + kTree + 24, uint64_t{1} << 40), "has its root beyond its buffer"},
        {with(nvdb, tile0 - 64 + 24, uint32_t{1} << 30), "has a root of 1073741824 tiles, beyond its buffer"},
        {with(nvdb, tile0 + 8, int64_t{-1} << 61), "does not lead to an upper internal node"},
        {with(nvdb, tile0 + 8, read<int64_t>(nvdb, tile0 + 8) + 32),
         "does not lead to an upper internal node"},
        {with(nvdb, tile0 + 32 + 8, read<int64_t>(nvdb, tile0 + 8)), "reaches an upper internal node twice"},
        {with(nvdb, tile0 + 32, read<uint64_t>(nvdb, tile0)), "two root entries at one origin"},
    };
    for (const auto& [bytes, reason] : hostile)
        EXPECT_NE(refusal(bytes).find(reason), std::string::npos) << reason << ": " << refusal(bytes);
}

// Random damage to a valid file: refused with VolumeError, or read with every invariant of a good one.
TEST(NvdbReader, RandomDamageIsRefusedOrReadWhole) {
    const std::string valid = nvdb_from_vdb(test::density_sphere_vdb(6, true));
    const size_t grid = test::nvdb_grid_offset(valid, 0);
    // Most of the file is the upper node's table of mostly zeros: half the damage lands in the headers.
    const size_t headers = grid + kTree + 64 + 64 + 8 * 32;
    const VolumeLimits limits{.max_box_voxels = uint64_t{1} << 21, .max_grids = 4};
    std::mt19937 random(39);
    int accepted = 0;
    for (int i = 0; i < 3000; ++i) {
        std::string bytes = valid;
        const int flips = 1 + int(random() % 4);
        for (int flip = 0; flip < flips; ++flip) {
            const size_t at = random() % 2 ? random() % headers : random() % bytes.size();
            bytes[at] = random() % 2 ? static_cast<char>(random() & 0xff)
                                     : static_cast<char>(bytes[at] ^ (1 << (random() % 8)));
        }
        VolumeReport report;
        try {
            report = inspect_vdb(bytes, limits);
        } catch (const VolumeError&) {
            continue;
        }
        ++accepted;
        for (const GridSummary& summary : report.grids) {
            if (!summary.usable) continue;
            for (size_t a = 0; a < 3; ++a) ASSERT_LE(summary.index_min[a], summary.index_max[a]);
            DensityGrid exported;
            try {
                exported = export_density(bytes, summary.name, limits, 64);
            } catch (const VolumeError&) {
                continue;
            }
            ASSERT_LE(exported.leaves.size(), 64u);
            std::set<std::array<int32_t, 3>> origins;
            for (const DensityLeaf& leaf : exported.leaves) {
                ASSERT_TRUE(origins.insert(leaf.origin).second);
                bool any = false;
                for (float value : leaf.values) {
                    ASSERT_TRUE(std::isfinite(value) && value >= 0.0f);
                    any = any || value > 0.0f;
                }
                // A leaf with a value holds an active voxel, so lies across the active box (an empty one
                // is exported too, as OpenVDB's are).
                for (size_t a = 0; a < 3; ++a) {
                    ASSERT_EQ(leaf.origin[a] % kLeafSide, 0);
                    if (!any) continue;
                    ASSERT_LE(leaf.origin[a], summary.index_max[a]);
                    ASSERT_GE(leaf.origin[a] + kLeafSide - 1, summary.index_min[a]);
                }
            }
        }
    }
    EXPECT_GT(accepted, 100);  // damage to values and unused bytes reads
}

TEST(NvdbReader, ApartItAnswersAsInThisProcess) {
    const std::filesystem::path checker = REFRACT_VDB_CHECK_PROGRAM;
    const std::string nvdb = nvdb_from_vdb(test::flame_vdb(4, 1200.0f));
    EXPECT_EQ(inspect_vdb_apart(nvdb, {}, checker), inspect_vdb(nvdb, {}));
    EXPECT_EQ(export_density_apart(nvdb, "temperature", {}, kMaxDensityLeaves, checker),
              export_density(nvdb, "temperature", {}));
}

}  // namespace
}  // namespace refract::volume
