// A float grid's active voxels exported for the daemon (volume/density_export.h): what OpenVDB holds, in a
// form the daemon reads with every length checked, whatever the exporter (or a subverted one) sends.
#include "volume/density_export.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>

#include "volume/vdb_check.h"
#include "volume/vdb_reader.h"
#include "volume/vdb_samples.h"

namespace refract::volume {
namespace {

const std::filesystem::path kChecker = REFRACT_VDB_CHECK_PROGRAM;

double total(const DensityGrid& grid) {
    double sum = 0.0;
    for (const DensityLeaf& leaf : grid.leaves)
        for (float value : leaf.values) sum += static_cast<double>(value);
    return sum;
}

std::string refusal(std::string_view bytes, uint64_t max_leaves = kMaxDensityLeaves) {
    try {
        decode_density(bytes, max_leaves);
    } catch (const VolumeError& e) {
        return e.what();
    }
    return "(decoded)";
}

TEST(DensityExport, HoldsEveryActiveVoxelAndTheTransform) {
    const DensityGrid sphere = export_density(test::density_sphere_vdb(6, true), "density", {});
    double expected = 0.0;
    for (int x = -6; x <= 6; ++x)
        for (int y = -6; y <= 6; ++y)
            for (int z = -6; z <= 6; ++z) expected += std::max(0.0, 1.0 - std::sqrt(double(x * x + y * y + z * z)) / 6.0);
    EXPECT_NEAR(total(sphere), expected, 1e-3);
    const std::array<double, 12> scaled{0.1, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, 0.1, 0};
    for (size_t i = 0; i < 12; ++i) EXPECT_NEAR(sphere.index_to_world[i], scaled[i], 1e-12) << i;
    // The centre voxel (index 0, 0, 0) holds 1, at (x * 8 + y) * 8 + z of the leaf at the origin.
    bool centre = false;
    for (const DensityLeaf& leaf : sphere.leaves)
        if (leaf.origin == std::array<int32_t, 3>{0, 0, 0}) centre = leaf.values[0] == 1.0f;
    EXPECT_TRUE(centre);
    // Active tiles (a constant box of 40^3 filled whole) come out as voxels: 125 leaves of 2s.
    const DensityGrid box = export_density(test::ramp_box_vdb({-16, -16, -16}, {23, 23, 23}, 0.05, 2.0f, 0.0f), "density", {});
    EXPECT_EQ(box.leaves.size(), 125u);
    EXPECT_DOUBLE_EQ(total(box), 2.0 * 40 * 40 * 40);
    // The exported form reads back as it was.
    EXPECT_EQ(decode_density(encode_density(sphere)), sphere);
}

TEST(DensityExport, RefusesWhatIsNoFloatGridOrTooLarge) {
    const std::string file = test::density_sphere_vdb(6, true);
    for (const char* grid : {"vel", "temperature"}) {
        try {
            export_density(file, grid, {});
            ADD_FAILURE() << grid;
        } catch (const VolumeError& e) {
            EXPECT_EQ(std::string(e.what()), std::string("no float grid named '") + grid + "' in the file");
        }
    }
    try {
        export_density(file, "density", {}, 1);
        ADD_FAILURE() << "exported past max_leaves";
    } catch (const VolumeError& e) {
        EXPECT_NE(std::string(e.what()).find("more than the 1 a scene takes"), std::string::npos) << e.what();
    }
}

TEST(DensityExport, ApartItAnswersAsInThisProcess) {
    const std::string file = test::ramp_box_vdb({0, -4, -4}, {23, 3, 3}, 0.05, 0.5f, 0.25f);
    EXPECT_EQ(export_density_apart(file, "density", {}, kMaxDensityLeaves, kChecker), export_density(file, "density", {}));
    try {
        export_density_apart(file, "vel", {}, kMaxDensityLeaves, kChecker);
        ADD_FAILURE() << "exported a grid the file lacks";
    } catch (const VolumeError& e) {
        EXPECT_STREQ(e.what(), "no float grid named 'vel' in the file");
    }
}

// Every field of the form broken in turn: each refused with its reason before anything is allocated.
TEST(DensityExport, HostileExportsAreRefusedWithTheReason) {
    const std::string valid = encode_density(export_density(test::density_sphere_vdb(6), "density", {}));
    ASSERT_EQ(valid.size(), kDensityHeaderBytes + 8 * kDensityLeafBytes);  // leaves at -8 and 0 on each axis
    auto with = [&](size_t at, const auto& value) {
        std::string bytes = valid;
        std::memcpy(bytes.data() + at, &value, sizeof value);
        return bytes;
    };
    const size_t leaf0 = kDensityHeaderBytes, values0 = leaf0 + 12;
    const struct {
        std::string bytes;
        const char* reason;
    } hostile[] = {
        {valid.substr(0, 50), "shorter than its header"},
        {"RFXDENS2" + valid.substr(8), "wrong magic number"},
        {with(12, uint32_t{1}), "a reserved word is not 0"},
        {with(8, uint32_t{0xffffffff}), "4294967295 leaves, more than the limit of 65536"},
        {with(8, uint32_t{9}), "leaves take"},
        {with(8, uint32_t{7}), "leaves take"},
        {valid + "x", "leaves take"},
        {valid.substr(0, valid.size() - 1), "leaves take"},
        {with(16, std::numeric_limits<double>::quiet_NaN()), "transform entry is not finite"},
        {with(16, 1e300), "transform entry is not finite or beyond 1e6"},
        {with(16, 0.0), "not invertible"},
        {with(leaf0, int32_t{3}), "not a multiple of 8"},
        {with(leaf0 + 4, int32_t{1} << 30), "within 2^28"},
        {with(leaf0 + kDensityLeafBytes, int32_t{-8}) .replace(leaf0 + kDensityLeafBytes + 4, 8, valid.substr(leaf0 + 4, 8)),
         "two leaves at one origin"},
        {with(values0, std::numeric_limits<float>::quiet_NaN()), "not finite and non-negative"},
        {with(values0 + 100, std::numeric_limits<float>::infinity()), "not finite and non-negative"},
        {with(values0 + 4 * 511, -1.0f), "not finite and non-negative"},
    };
    for (const auto& [bytes, reason] : hostile)
        EXPECT_NE(refusal(bytes).find(reason), std::string::npos) << reason << ": " << refusal(bytes);
    EXPECT_NE(refusal(valid, 7).find("8 leaves, more than the limit of 7"), std::string::npos);

    // Random damage: read or refused, never more.
    std::mt19937 random(39);
    for (int i = 0; i < 3000; ++i) {
        std::string bytes = valid.substr(0, random() % 2 ? valid.size() : random() % valid.size());
        for (int flips = 0; flips < 4 && !bytes.empty(); ++flips)
            bytes[random() % bytes.size()] = static_cast<char>(random() & 0xff);
        try {
            decode_density(bytes);
        } catch (const VolumeError&) {
        }
    }
}

// An exporter whose answer is not the form (a subverted one, say) is refused, however long it goes on.
TEST(DensityExport, AnExportersAnswerIsReadNoFurtherThanItsLimit) {
    auto script = [](const std::string& name, const std::string& body) {
        const auto path = std::filesystem::path(testing::TempDir()) / name;
        std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
        std::filesystem::permissions(path, std::filesystem::perms::owner_all);
        return path;
    };
    const auto refused = [](const std::filesystem::path& program) -> std::string {
        try {
            export_density_apart("x", "density", {}, 1, program);
        } catch (const VolumeError& e) {
            return e.what();
        }
        return "(exported)";
    };
    EXPECT_NE(refused(script("junk", "printf DRFXDENS1; head -c 300 /dev/zero")).find("density export:"), std::string::npos);
    EXPECT_NE(refused(script("endless", "printf D; exec yes")).find("density export: not one (wrong magic number)"),
              std::string::npos);
    EXPECT_EQ(refused(script("refuses", "printf 'Eno good'")), "no good");
}

}  // namespace
}  // namespace refract::volume
