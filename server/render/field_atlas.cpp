#include "render/field_atlas.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace refract::scene {

namespace {
using Box = std::pair<glm::uvec3, glm::uvec3>;  // [first, end)

bool overlap(const Box& a, const Box& b) {
    return glm::all(glm::lessThan(a.first, b.second)) && glm::all(glm::lessThan(b.first, a.second));
}

// Cells occupied by a cluster, coarsened `level` times (a cell of level j spans 2^j map cells a side).
struct Occupancy {
    glm::uvec3 dims;
    std::vector<uint8_t> taken;
    bool at(glm::uvec3 c) const { return taken[(size_t{c.z} * dims.y + c.y) * dims.x + c.x] != 0; }
};

// The map: where each cluster's cells lie in the atlas, then for each empty cell the largest aligned cube of
// cells around it that no cluster meets, from an occupancy pyramid (level j: cubes of 2^j cells).
void fill_map(FieldAtlas& atlas, const std::vector<Box>& joined, glm::uvec3 cells, uint32_t max_level) {
    std::vector<Occupancy> pyramid{{cells, std::vector<uint8_t>(size_t{cells.x} * cells.y * cells.z, 0)}};
    atlas.map.assign(pyramid[0].taken.size(), 0u);
    auto index = [](glm::uvec3 d, glm::uvec3 c) { return (size_t{c.z} * d.y + c.y) * d.x + c.x; };
    for (size_t k = 0; k < joined.size(); ++k) {
        const glm::uvec3 end = glm::min(joined[k].second, cells);
        const glm::uvec3 atlas_first = atlas.clusters[k].atlas_first / FIELD_CELL;
        for (uint32_t z = joined[k].first.z; z < end.z; ++z)
            for (uint32_t y = joined[k].first.y; y < end.y; ++y)
                for (uint32_t x = joined[k].first.x; x < end.x; ++x) {
                    const glm::uvec3 a = glm::uvec3(x, y, z) - joined[k].first + atlas_first;
                    pyramid[0].taken[index(cells, {x, y, z})] = 1;
                    atlas.map[index(cells, {x, y, z})] = a.x | (a.y << FIELD_AXIS_BITS) | (a.z << (2 * FIELD_AXIS_BITS));
                }
    }
    const uint32_t top = max_level > FIELD_CELL_LEVEL ? max_level - FIELD_CELL_LEVEL : 0;
    for (uint32_t j = 1; j <= top; ++j) {
        const Occupancy& below = pyramid.back();
        Occupancy level{(below.dims + 1u) / 2u, {}};
        level.taken.assign(size_t{level.dims.x} * level.dims.y * level.dims.z, 0);
        for (uint32_t z = 0; z < below.dims.z; ++z)
            for (uint32_t y = 0; y < below.dims.y; ++y)
                for (uint32_t x = 0; x < below.dims.x; ++x)
                    if (below.at({x, y, z})) level.taken[index(level.dims, glm::uvec3(x, y, z) / 2u)] = 1;
        pyramid.push_back(std::move(level));
    }
    const uint32_t lowest = std::min(max_level, FIELD_CELL_LEVEL);
    for (uint32_t z = 0; z < cells.z; ++z)
        for (uint32_t y = 0; y < cells.y; ++y)
            for (uint32_t x = 0; x < cells.x; ++x) {
                const glm::uvec3 c(x, y, z);
                if (pyramid[0].at(c)) continue;
                uint32_t j = 0;
                while (j < top && !pyramid[j + 1].at(c >> (j + 1))) ++j;
                atlas.map[index(cells, c)] = FIELD_EMPTY + (j == 0 ? lowest : FIELD_CELL_LEVEL + j);
            }
}

}  // namespace

std::optional<glm::uvec3> FieldAtlas::atlas_voxel(glm::uvec3 v) const {
    if (dense) return clusters.front().contains(v) ? std::optional(v) : std::nullopt;
    const uint32_t entry = map_entry(v / FIELD_CELL);
    if (entry & FIELD_EMPTY) return std::nullopt;
    const uint32_t mask = (1u << FIELD_AXIS_BITS) - 1u;
    const glm::uvec3 atlas_cell(entry & mask, (entry >> FIELD_AXIS_BITS) & mask, (entry >> (2 * FIELD_AXIS_BITS)) & mask);
    return atlas_cell * FIELD_CELL + v % FIELD_CELL;
}

FieldAtlas dense_field_atlas(const passes::GridGeometry& lattice) {
    FieldAtlas atlas;
    atlas.clusters = {{glm::uvec3(0u), glm::uvec3(lattice.dims.x, lattice.dims.y, lattice.dims.z), glm::uvec3(0u)}};
    atlas.dims = lattice.dims;
    return atlas;
}

FieldAtlas sparse_field_atlas(const passes::GridGeometry& lattice, std::span<const std::pair<glm::uvec3, glm::uvec3>> boxes,
                              uint32_t max_level, uint32_t max_side) {
    const glm::uvec3 dims(lattice.dims.x, lattice.dims.y, lattice.dims.z);
    const glm::uvec3 cells = (dims + FIELD_CELL - 1u) / FIELD_CELL;
    // The boxes in whole cells, joined until no two share one (a join can reach a third box).
    std::vector<Box> joined;
    for (const auto& [first, end] : boxes)
        if (glm::all(glm::lessThan(first, end))) joined.push_back({first / FIELD_CELL, (end + FIELD_CELL - 1u) / FIELD_CELL});
    for (bool again = true; again;) {
        again = false;
        for (size_t i = 0; i < joined.size() && !again; ++i)
            for (size_t j = i + 1; j < joined.size() && !again; ++j)
                if (overlap(joined[i], joined[j])) {
                    joined[i] = {glm::min(joined[i].first, joined[j].first), glm::max(joined[i].second, joined[j].second)};
                    joined.erase(joined.begin() + static_cast<std::ptrdiff_t>(j));
                    again = true;
                }
    }
    // Numbered in lattice order, so that the same boxes give the same layout.
    std::sort(joined.begin(), joined.end(), [](const Box& a, const Box& b) {
        return std::tie(a.first.z, a.first.y, a.first.x) < std::tie(b.first.z, b.first.y, b.first.x);
    });
    FieldAtlas atlas;
    atlas.dense = false;
    atlas.cells = {cells.x, cells.y, cells.z};
    for (const Box& b : joined)
        atlas.clusters.push_back({b.first * FIELD_CELL, glm::min(b.second * FIELD_CELL, dims), glm::uvec3(0u)});

    // Packing: slots of whole cells (the octree's nodes up to FIELD_CELL voxels then lie in one cluster, as
    // in the lattice), deepest first, in rows along x, rows along y into layers, layers along z; of the
    // row widths and layer heights tried, the one that gives the smallest atlas.
    std::vector<size_t> order(joined.size());
    std::iota(order.begin(), order.end(), size_t{0});
    auto slot = [&](size_t i) { return (joined[i].second - joined[i].first) * FIELD_CELL; };
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
        const glm::uvec3 sa = slot(a), sb = slot(b);
        return std::tie(sb.z, sb.y, sb.x, a) < std::tie(sa.z, sa.y, sa.x, b);
    });
    max_side = std::min(max_side, FIELD_CELL << FIELD_AXIS_BITS);
    glm::uvec3 widest(FIELD_CELL), total(0u);
    for (size_t i : order) {
        widest = glm::max(widest, slot(i));
        total += slot(i);
    }
    struct Packing {
        std::vector<glm::uvec3> at;
        glm::uvec3 used{0u};
    };
    auto pack = [&](uint32_t row_width, uint32_t layer_height) {
        Packing p{std::vector<glm::uvec3>(joined.size()), glm::uvec3(0u)};
        glm::uvec3 at(0u);
        uint32_t row_height = 0, layer_depth = 0;
        for (size_t i : order) {
            const glm::uvec3 s = slot(i);
            if (at.x > 0 && at.x + s.x > row_width) {  // the next row
                at = {0u, at.y + row_height, at.z};
                row_height = 0;
            }
            if (at.y > 0 && at.y + s.y > layer_height) {  // the next layer
                at = {0u, 0u, at.z + layer_depth};
                layer_depth = 0;
            }
            p.at[i] = at;
            p.used = glm::max(p.used, at + s);
            at.x += s.x;
            row_height = std::max(row_height, s.y);
            layer_depth = std::max(layer_depth, s.z);
        }
        return p;
    };
    auto volume = [](glm::uvec3 d) { return double(d.x) * d.y * d.z; };
    auto fits = [&](const Packing& p) { return glm::all(glm::lessThanEqual(p.used, glm::uvec3(max_side))); };
    // About 32 widths and heights between the widest slot and all of them side by side.
    auto tries = [](uint32_t lo, uint32_t hi) {
        std::vector<uint32_t> out;
        const uint32_t step = std::max(FIELD_CELL, (hi > lo ? hi - lo : 0u) / 32u / FIELD_CELL * FIELD_CELL);
        for (uint32_t v = lo; v < hi; v += step) out.push_back(v);
        out.push_back(std::max(lo, hi));
        return out;
    };
    Packing best = pack(max_side, max_side);
    for (uint32_t width : tries(widest.x, total.x))
        for (uint32_t height : tries(widest.y, total.y)) {
            Packing p = pack(width, height);
            if (fits(p) && (!fits(best) || volume(p.used) < volume(best.used))) best = std::move(p);
        }
    const glm::uvec3 used = best.used;
    if (!fits(best))
        throw std::length_error("the objects' boxes need a field atlas of " + std::to_string(used.x) + " x " +
                                std::to_string(used.y) + " x " + std::to_string(used.z) + " voxels; the device allows " +
                                std::to_string(max_side) + " a side");
    for (size_t i = 0; i < joined.size(); ++i) atlas.clusters[i].atlas_first = best.at[i];
    atlas.dims = {std::max(used.x, 1u), std::max(used.y, 1u), std::max(used.z, 1u)};

    fill_map(atlas, joined, cells, max_level);
    return atlas;
}

}  // namespace refract::scene
