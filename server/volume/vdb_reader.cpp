#include "volume/vdb_reader.h"

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>

#include "volume/grid_checks.h"
#include "volume/nvdb_reader.h"
#include "volume/vdb_layout.h"

namespace refract::volume {

namespace {

// The first bytes of a file: OpenVDB's magic number (an int64, little-endian). NanoVDB's go to
// nvdb_reader.h.
constexpr unsigned char kVdbMagic[8] = {0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0};

// Checks one float grid and fills in its summary; throws VolumeError naming it.
void check_float_grid(const openvdb::FloatGrid& grid, const std::string& what, const VolumeLimits& limits,
                      GridSummary& summary) {
    const openvdb::math::Transform& transform = grid.transform();
    if (!transform.isLinear())
        throw VolumeError("grid " + what +
                          " has a non-linear (frustum) transform; only linear ones are read");
    const openvdb::Vec3d voxel = transform.voxelSize();
    for (int axis = 0; axis < 3; ++axis)
        if (!std::isfinite(voxel[axis]) || voxel[axis] <= 0)
            throw VolumeError("grid " + what + " has a voxel size that is not finite and positive");
    summary.voxel_size = {voxel[0], voxel[1], voxel[2]};

    const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
    if (box.empty()) {
        summary.unusable_reason = "no active voxels";
        return;
    }
    // Coord::dim is 32-bit and wraps for a box across the whole index range: widened first.
    check_active_box({int64_t{box.max().x()} - box.min().x() + 1, int64_t{box.max().y()} - box.min().y() + 1,
                      int64_t{box.max().z()} - box.min().z() + 1},
                     what, limits);
    check_grid_value(grid.background(), what, "as its background");
    for (auto value = grid.cbeginValueOn(); value; ++value) check_grid_value(*value, what, "in an active voxel");

    summary.active_voxels = grid.activeVoxelCount();
    summary.index_min = {box.min().x(), box.min().y(), box.min().z()};
    summary.index_max = {box.max().x(), box.max().y(), box.max().z()};
    // The world box holds the index box's eight corners (voxel centres at integer coordinates).
    summary.world_min.fill(std::numeric_limits<double>::infinity());
    summary.world_max.fill(-std::numeric_limits<double>::infinity());
    for (int corner = 0; corner < 8; ++corner) {
        const openvdb::Vec3d index((corner & 1) ? box.max().x() : box.min().x(),
                                   (corner & 2) ? box.max().y() : box.min().y(),
                                   (corner & 4) ? box.max().z() : box.min().z());
        const openvdb::Vec3d world = transform.indexToWorld(index);
        for (int axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<size_t>(axis);
            summary.world_min[a] = std::min(summary.world_min[a], world[axis]);
            summary.world_max[a] = std::max(summary.world_max[a], world[axis]);
        }
    }
    summary.usable = true;
}

// The oldest format version read: OpenVDB 3.0's, the first with per-grid compression flags.
constexpr uint32_t kOldestVersion = 222;

openvdb::GridPtrVec read_grids(std::string_view bytes, uint32_t max_grids) {
    if (bytes.size() < sizeof kVdbMagic || std::memcmp(bytes.data(), kVdbMagic, sizeof kVdbMagic) != 0)
        throw VolumeError("not an OpenVDB file (it does not start with the VDB magic number)");
    // OpenVDB only warns about a format version it cannot read, and then reads no grids.
    uint32_t version = 0;
    if (bytes.size() >= sizeof kVdbMagic + sizeof version)
        std::memcpy(&version, bytes.data() + sizeof kVdbMagic, sizeof version);
    if (version > openvdb::OPENVDB_FILE_VERSION || version < kOldestVersion)
        throw VolumeError("not a readable OpenVDB file: its format version " + std::to_string(version) +
                          " is outside what this build reads (" + std::to_string(kOldestVersion) + " to " +
                          std::to_string(openvdb::OPENVDB_FILE_VERSION) + ")");
    const std::vector<std::string> streams = split_grids(bytes, max_grids);
    openvdb::initialize();
    try {
        openvdb::GridPtrVec grids;
        for (const std::string& one_grid : streams) {
            std::istringstream in(one_grid, std::ios::binary);
            // A read past the end throws at once: OpenVDB does not check its reads, and would otherwise
            // take the uninitialised size after a truncation as a length to allocate.
            in.exceptions(std::ios::failbit | std::ios::badbit);
            openvdb::io::Stream stream(in, /*delayLoad=*/false);
            for (const openvdb::GridBase::Ptr& grid : *stream.getGrids()) grids.push_back(grid);
        }
        return grids;
    } catch (const std::ios_base::failure&) {
        throw VolumeError("not a readable OpenVDB file: it ends before its grids do (truncated?)");
    } catch (const openvdb::LookupError& e) {
        throw VolumeError(
            std::string("a grid of a type OpenVDB does not know (only the standard 5-4-3 tree is "
                        "read): ") +
            e.what());
    } catch (const std::exception& e) {
        throw VolumeError(std::string("not a readable OpenVDB file (truncated or damaged?): ") + e.what());
    }
}

}  // namespace

VolumeLimits limits_for_resolution(uint32_t max_resolution) {
    const uint64_t side = max_resolution;
    return {.max_box_voxels = side * side * side};
}

VolumeReport inspect_vdb(std::string_view bytes, const VolumeLimits& limits) {
    if (is_nanovdb(bytes)) {
        VolumeReport report{inspect_nvdb(bytes, limits)};
        require_usable_grid(report);
        return report;
    }
    const openvdb::GridPtrVec grids = read_grids(bytes, limits.max_grids);
    VolumeReport report;
    for (size_t i = 0; i < grids.size(); ++i) {
        const openvdb::GridBase& grid = *grids[i];
        GridSummary summary;
        summary.name = grid.getName();
        summary.type = grid.valueType();
        const std::string what = grid_label(grid.getName(), i);
        if (const auto floats = openvdb::GridBase::constGrid<openvdb::FloatGrid>(grids[i]))
            check_float_grid(*floats, what, limits, summary);
        else if (summary.type == "float")
            throw VolumeError("grid " + what + " is a float grid with the tree " + grid.type() +
                              "; only OpenVDB's standard 5-4-3 tree (Tree_float_5_4_3) is read");
        else
            summary.unusable_reason = "a " + summary.type + " grid; only float grids are read";
        report.grids.push_back(std::move(summary));
    }
    require_usable_grid(report);
    return report;
}
DensityGrid export_density(std::string_view bytes, const std::string& grid_name, const VolumeLimits& limits,
                           uint64_t max_leaves) {
    if (is_nanovdb(bytes)) return export_nvdb_density(bytes, grid_name, limits, max_leaves);
    const openvdb::GridPtrVec grids = read_grids(bytes, limits.max_grids);
    for (size_t i = 0; i < grids.size(); ++i) {
        if (grids[i]->getName() != grid_name) continue;
        const auto floats = openvdb::GridBase::constGrid<openvdb::FloatGrid>(grids[i]);
        if (!floats) continue;
        GridSummary summary;
        check_float_grid(*floats, grid_name, limits, summary);
        if (!summary.usable) throw VolumeError("grid " + quoted(grid_name) + " has " + summary.unusable_reason);
        // Tiles become voxels, so that every active value lies in a leaf; the box check above bounds them.
        openvdb::FloatGrid::Ptr copy = floats->deepCopy();
        copy->tree().voxelizeActiveTiles();
        const openvdb::Index64 leaves = copy->tree().leafCount();
        if (leaves > max_leaves)
            throw VolumeError("grid " + quoted(grid_name) + " has " + std::to_string(leaves) +
                              " leaves of 8^3 voxels, more than the " + std::to_string(max_leaves) + " a scene takes");
        DensityGrid out;
        const openvdb::math::Transform& transform = copy->transform();
        const openvdb::Vec3d origin = transform.indexToWorld(openvdb::Vec3d(0, 0, 0));
        for (int axis = 0; axis < 3; ++axis) {
            openvdb::Vec3d unit(0, 0, 0);
            unit[axis] = 1;
            const openvdb::Vec3d column = transform.indexToWorld(unit) - origin;
            for (int row = 0; row < 3; ++row) out.index_to_world[static_cast<size_t>(row * 4 + axis)] = column[row];
        }
        for (int row = 0; row < 3; ++row) out.index_to_world[static_cast<size_t>(row * 4 + 3)] = origin[row];
        out.leaves.reserve(leaves);
        for (auto leaf = copy->tree().cbeginLeaf(); leaf; ++leaf) {
            DensityLeaf& kept = out.leaves.emplace_back();
            kept.origin = {leaf->origin().x(), leaf->origin().y(), leaf->origin().z()};
            for (openvdb::Index offset = 0; offset < kLeafVoxels; ++offset)
                kept.values[offset] = leaf->isValueOn(offset) ? leaf->getValue(offset) : 0.0f;
        }
        return out;
    }
    throw VolumeError("no float grid named " + quoted(grid_name) + " in the file");
}

nlohmann::json to_json(const VolumeReport& report) {
    nlohmann::json grids = nlohmann::json::array();
    for (const GridSummary& g : report.grids) {
        nlohmann::json j = {{"name", g.name}, {"type", g.type}, {"usable", g.usable}};
        if (!g.usable) {
            j["unusable_reason"] = g.unusable_reason;
        } else {
            j["active_voxels"] = g.active_voxels;
            j["index_bounds"] = {{"min", g.index_min}, {"max", g.index_max}};
            j["world_bounds"] = {{"min", g.world_min}, {"max", g.world_max}};
            j["voxel_size"] = g.voxel_size;
        }
        grids.push_back(std::move(j));
    }
    return {{"grids", grids}};
}

VolumeReport volume_report_from_json(const nlohmann::json& j) {
    VolumeReport report;
    for (const nlohmann::json& g : j.at("grids")) {
        GridSummary summary;
        summary.name = g.at("name").get<std::string>();
        summary.type = g.at("type").get<std::string>();
        summary.usable = g.at("usable").get<bool>();
        if (!summary.usable) {
            summary.unusable_reason = g.at("unusable_reason").get<std::string>();
        } else {
            summary.active_voxels = g.at("active_voxels").get<uint64_t>();
            g.at("index_bounds").at("min").get_to(summary.index_min);
            g.at("index_bounds").at("max").get_to(summary.index_max);
            g.at("world_bounds").at("min").get_to(summary.world_min);
            g.at("world_bounds").at("max").get_to(summary.world_max);
            g.at("voxel_size").get_to(summary.voxel_size);
        }
        report.grids.push_back(std::move(summary));
    }
    return report;
}

}  // namespace refract::volume
