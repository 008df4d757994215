#include "volume/vdb_samples.h"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace refract::test {

namespace {

// As a DCC writes it: through io::File, which records each grid's offsets.
std::string write(const openvdb::GridPtrVec& grids) {
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("refract_vdb_" + std::to_string(::getpid()) + ".vdb");
    openvdb::io::File file(path.string());
    file.write(grids);
    file.close();
    std::ifstream in(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    std::filesystem::remove(path);
    return bytes.str();
}

// Without offsets: io::Stream writes each grid where the previous one's tree ends.
std::string write_stream(const openvdb::GridPtrVec& grids) {
    std::ostringstream out(std::ios::binary);
    openvdb::io::Stream(out).write(grids);
    return out.str();
}

openvdb::FloatGrid::Ptr density_grid() {
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
    return grid;
}

}  // namespace

std::string density_sphere_vdb(int radius, bool with_velocity) {
    auto grid = density_grid();
    auto access = grid->getAccessor();
    for (int x = -radius; x <= radius; ++x)
        for (int y = -radius; y <= radius; ++y)
            for (int z = -radius; z <= radius; ++z) {
                const double r = std::sqrt(double(x * x + y * y + z * z)) / radius;
                if (r < 1) access.setValue(openvdb::Coord(x, y, z), float(1 - r));
            }
    openvdb::GridPtrVec grids{grid};
    if (with_velocity) {
        auto velocity = openvdb::Vec3SGrid::create();
        velocity->setName("vel");
        velocity->tree().setValue(openvdb::Coord(0, 0, 0), openvdb::Vec3s(0, 1, 0));
        grids.push_back(velocity);
    }
    return write(grids);
}

std::string flame_vdb(int radius, float kelvin) {
    auto density = density_grid();
    auto temperature = density_grid();
    temperature->setName("temperature");
    auto heat = density_grid();
    heat->setName("heat");
    auto d = density->getAccessor(), t = temperature->getAccessor(), h = heat->getAccessor();
    for (int x = -radius; x <= radius; ++x)
        for (int y = -radius; y <= radius; ++y)
            for (int z = -radius; z <= radius; ++z) {
                const double r = std::sqrt(double(x * x + y * y + z * z)) / radius;
                if (r >= 1) continue;
                const openvdb::Coord at(x, y, z);
                d.setValue(at, float(1 - r));
                h.setValue(at, float(1 - r));
                t.setValue(at, kelvin * float(1 - r));
            }
    return write({density, temperature, heat});
}

std::string vdb_of(const volume::DensityGrid& grid, const std::string& name) {
    auto out = density_grid();
    out->setName(name);
    const auto& m = grid.index_to_world;
    out->setTransform(openvdb::math::Transform::createLinearTransform(
        openvdb::math::Mat4d(m[0], m[4], m[8], 0.0, m[1], m[5], m[9], 0.0, m[2], m[6], m[10], 0.0, m[3], m[7], m[11], 1.0)));
    auto access = out->getAccessor();
    for (const volume::DensityLeaf& leaf : grid.leaves)
        for (size_t i = 0; i < volume::kLeafVoxels; ++i)
            if (leaf.values[i] != 0.0f)
                access.setValue(openvdb::Coord(leaf.origin[0] + static_cast<int>(i / 64), leaf.origin[1] + static_cast<int>(i / 8 % 8),
                                               leaf.origin[2] + static_cast<int>(i % 8)),
                                leaf.values[i]);
    return write({out});
}

std::string ramp_box_vdb(const std::array<int, 3>& lo, const std::array<int, 3>& hi, double voxel, float a, float b,
                         const std::string& name) {
    auto grid = density_grid();
    grid->setName(name);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
    const openvdb::CoordBBox box(openvdb::Coord(lo[0], lo[1], lo[2]), openvdb::Coord(hi[0], hi[1], hi[2]));
    if (b == 0.0f) {
        grid->fill(box, a, true);
    } else {
        auto access = grid->getAccessor();
        for (auto ijk = box.begin(); ijk; ++ijk) access.setValue(*ijk, a + b * static_cast<float>((*ijk).x()));
    }
    return write({grid});
}

std::string as_stream_vdb(bool with_velocity) {
    auto grid = density_grid();
    grid->tree().setValue(openvdb::Coord(1, 2, 3), 0.5f);
    openvdb::GridPtrVec grids{grid};
    if (with_velocity) {
        auto velocity = openvdb::Vec3SGrid::create();
        velocity->setName("vel");
        grids.push_back(velocity);
    }
    return write_stream(grids);
}

std::string metadata_bomb_vdb() {
    auto grid = density_grid();
    grid->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    grid->insertMeta("comment", openvdb::StringMetadata("BOMB"));
    std::string bytes = write({grid});
    // The string's value is written as its length (4) and "BOMB"; the length becomes 2^32 - 1.
    const size_t at = bytes.find("BOMB");
    const uint32_t declared = 0xffffffffu;
    std::memcpy(&bytes[at - sizeof declared], &declared, sizeof declared);
    return bytes;
}

std::string vector_only_vdb() {
    openvdb::initialize();
    auto velocity = openvdb::Vec3SGrid::create();
    velocity->setName("vel");
    velocity->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(0, 1, 0));
    return write({velocity});
}

std::string density_with_value_vdb(float bad) {
    auto grid = density_grid();
    for (int x = 0; x < 4; ++x) grid->tree().setValue(openvdb::Coord(x, 0, 0), 0.5f);
    grid->tree().setValue(openvdb::Coord(2, 1, 0), bad);
    return write({grid});
}

std::string far_apart_vdb(int apart) {
    auto grid = density_grid();
    grid->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    grid->tree().setValue(openvdb::Coord(apart, apart, apart), 1.0f);
    return write({grid});
}

std::string deep_tree_vdb() {
    using DeepTree = openvdb::tree::Tree5<float, 6, 5, 4, 3>::Type;
    using DeepGrid = openvdb::Grid<DeepTree>;
    openvdb::initialize();
    if (!DeepGrid::isRegistered()) DeepGrid::registerGrid();
    auto grid = DeepGrid::create(0.0f);
    grid->setName("density");
    grid->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    std::string bytes = write({grid});
    DeepGrid::unregisterGrid();
    return bytes;
}

}  // namespace refract::test
