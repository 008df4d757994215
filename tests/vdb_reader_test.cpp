// Volume assets: OpenVDB files written by OpenVDB in the test, read back and summarised, and every
// hostile file refused with its reason.
#include "volume/vdb_reader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "volume/nvdb_samples.h"
#include "volume/vdb_samples.h"

namespace refract::volume {
namespace {

using test::density_sphere_vdb;

// The message of the VolumeError `bytes` are refused with.
std::string refusal(const std::string& bytes, const VolumeLimits& limits = {}) {
    return test::volume_refusal(bytes, limits);
}

TEST(VdbReader, SummarisesADensitySphere) {
    const VolumeReport report = inspect_vdb(density_sphere_vdb(8), {});
    ASSERT_EQ(report.grids.size(), 1u);
    const GridSummary& grid = report.grids[0];
    EXPECT_EQ(grid.name, "density");
    EXPECT_EQ(grid.type, "float");
    EXPECT_TRUE(grid.usable);
    // The sphere's voxels have r < 8: the box is [-7, 7] on each axis.
    EXPECT_EQ(grid.index_min, (std::array<int32_t, 3>{-7, -7, -7}));
    EXPECT_EQ(grid.index_max, (std::array<int32_t, 3>{7, 7, 7}));
    for (size_t axis = 0; axis < 3; ++axis) {
        EXPECT_NEAR(grid.voxel_size[axis], 0.1, 1e-12);
        EXPECT_NEAR(grid.world_min[axis], -0.7, 1e-9);
        EXPECT_NEAR(grid.world_max[axis], 0.7, 1e-9);
    }
    EXPECT_GT(grid.active_voxels, 4u * 7 * 7 * 7);  // about 4/3 pi 7.5^3
    EXPECT_LT(grid.active_voxels, 15u * 15 * 15);
    EXPECT_EQ(volume_report_from_json(to_json(report)), report);
}

TEST(VdbReader, ListsOtherGridTypesAsUnusable) {
    const VolumeReport report = inspect_vdb(density_sphere_vdb(4, true), {});
    ASSERT_EQ(report.grids.size(), 2u);
    EXPECT_TRUE(report.grids[0].usable);
    EXPECT_EQ(report.grids[1].name, "vel");
    EXPECT_EQ(report.grids[1].type, "vec3s");
    EXPECT_FALSE(report.grids[1].usable);
    EXPECT_NE(report.grids[1].unusable_reason.find("only float grids"), std::string::npos);
    EXPECT_EQ(volume_report_from_json(to_json(report)), report);
}

TEST(VdbReader, RefusesAFileWithoutAFloatGrid) {
    const std::string why = refusal(test::vector_only_vdb());
    EXPECT_NE(why.find("no usable float grid"), std::string::npos) << why;
    EXPECT_NE(why.find("'vel'"), std::string::npos) << why;
}

TEST(VdbReader, RefusesNonFiniteAndNegativeValuesNamingTheGrid) {
    for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
        const std::string why = refusal(test::density_with_value_vdb(bad));
        EXPECT_NE(why.find("grid 'density' holds a non-finite value"), std::string::npos) << why;
    }
    const std::string why = refusal(test::density_with_value_vdb(-0.25f));
    EXPECT_NE(why.find("grid 'density' holds a negative value"), std::string::npos) << why;
}

TEST(VdbReader, RefusesAHugeActiveBoundingBox) {
    // Two voxels make a box of 1e6^3 voxels, which overflows 64 bits if multiplied as integers.
    const std::string why = refusal(test::far_apart_vdb(1'000'000));
    EXPECT_NE(why.find("active bounding box of grid 'density' spans 1000001 x 1000001 x 1000001"),
              std::string::npos)
        << why;
    // The limit is the daemon's: the same box of 9^3 passes 729 and fails 728.
    EXPECT_NO_THROW(inspect_vdb(test::far_apart_vdb(8), {.max_box_voxels = 729}));
    EXPECT_NE(refusal(test::far_apart_vdb(8), {.max_box_voxels = 728}).find("limit of 728"),
              std::string::npos);
}

TEST(VdbReader, RefusesATreeDeeperThanOpenVdbs) {
    const std::string why = refusal(test::deep_tree_vdb());
    EXPECT_NE(why.find("5-4-3"), std::string::npos) << why;
}

TEST(VdbReader, RefusesTooManyGrids) {
    const std::string why = refusal(density_sphere_vdb(2, true), {.max_grids = 1});
    EXPECT_NE(why.find("holds 2 grids, more than the limit of 1"), std::string::npos) << why;
}

TEST(VdbReader, ReadsASingleGridStreamAndRefusesSeveralWithoutOffsets) {
    EXPECT_EQ(inspect_vdb(test::as_stream_vdb(false), {}).grids.size(), 1u);
    const std::string why = refusal(test::as_stream_vdb(true));
    EXPECT_NE(why.find("2 grids without offsets to their ends"), std::string::npos) << why;
}

// OpenVDB would allocate and fill the declared 4 GiB before reading the 4 bytes present.
TEST(VdbReader, RefusesAMetadataLengthBeyondTheFile) {
    const std::string why = refusal(test::metadata_bomb_vdb());
    EXPECT_NE(why.find("it ends inside a metadata value of grid 'density' (4294967295 bytes declared"),
              std::string::npos)
        << why;
}

// A file with offsets is cut inside what they bound; a stream without them inside the tree OpenVDB reads.
TEST(VdbReader, RefusesEveryTruncationOfAValidFile) {
    for (const std::string& file : {density_sphere_vdb(6, true), test::as_stream_vdb(false)}) {
        for (size_t length = 0; length < file.size(); length += std::max<size_t>(1, file.size() / 97)) {
            const std::string why = refusal(file.substr(0, length));
            EXPECT_TRUE(why.find("not an OpenVDB file") != std::string::npos ||
                        why.find("not a readable OpenVDB file") != std::string::npos)
                << length << " of " << file.size() << " bytes: " << why;
            // A size read past the end was never taken for an allocation's.
            EXPECT_EQ(why.find("bad_alloc"), std::string::npos) << length << " bytes: " << why;
        }
    }
}

TEST(VdbReader, RefusesRandomBytes) {
    std::mt19937 random(39);
    std::string noise(4096, '\0');
    for (char& c : noise) c = static_cast<char>(random() & 0xff);
    EXPECT_NE(refusal(noise).find("not an OpenVDB file"), std::string::npos);
    // Noise after a valid magic number reaches OpenVDB's own reader, which must refuse it too.
    const std::string file = density_sphere_vdb(2);
    const std::string why = refusal(file.substr(0, 8) + noise);
    EXPECT_NE(why.find("not a readable OpenVDB file"), std::string::npos) << why;
    // Noise after NanoVDB's magic number is read as NanoVDB (nvdb_reader_test.cpp), and refused.
    EXPECT_NE(refusal("NanoVDB0" + noise).find("not a readable NanoVDB file"), std::string::npos);
}

}  // namespace
}  // namespace refract::volume
