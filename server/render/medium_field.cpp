#include "render/medium_field.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <bit>
#include <limits>
#include <numbers>
#include <unordered_map>

#include "assets/render_error.h"
#include "mesh/mesh.h"
#include "render/blackbody.h"

namespace refract::scene {

namespace {

// A grid's values by voxel: its leaves found by origin.
class DensityLookup {
public:
    explicit DensityLookup(const volume::DensityGrid& grid) : grid_(grid) {
        leaves_.reserve(grid.leaves.size());
        for (size_t i = 0; i < grid.leaves.size(); ++i) leaves_.emplace(grid.leaves[i].origin, i);
    }

    float at(glm::ivec3 v) const {
        const glm::ivec3 origin = floor8(v);
        const auto it = leaves_.find(Key{origin.x, origin.y, origin.z});
        if (it == leaves_.end()) return 0.0f;
        const glm::ivec3 in = v - origin;
        return grid_.leaves[it->second].values[static_cast<size_t>((in.x * 8 + in.y) * 8 + in.z)];
    }

    // Trilinear between voxel centres (at integer index coordinates).
    double trilinear(glm::dvec3 index) const {
        const glm::dvec3 base = glm::floor(index);
        const glm::dvec3 f = index - base;
        const glm::ivec3 v(base);
        double sum = 0.0;
        for (int corner = 0; corner < 8; ++corner) {
            const glm::ivec3 o((corner & 1), (corner >> 1) & 1, (corner >> 2) & 1);
            const double w = (o.x ? f.x : 1.0 - f.x) * (o.y ? f.y : 1.0 - f.y) * (o.z ? f.z : 1.0 - f.z);
            if (w > 0.0) sum += w * static_cast<double>(at(v + o));
        }
        return sum;
    }

private:
    static glm::ivec3 floor8(glm::ivec3 v) { return {v.x & ~7, v.y & ~7, v.z & ~7}; }
    using Key = std::array<int32_t, 3>;
    struct Hash {
        size_t operator()(const Key& k) const {
            return (static_cast<size_t>(static_cast<uint32_t>(k[0])) * 73856093u) ^
                   (static_cast<size_t>(static_cast<uint32_t>(k[1])) * 19349663u) ^
                   (static_cast<size_t>(static_cast<uint32_t>(k[2])) * 83492791u);
        }
    };
    const volume::DensityGrid& grid_;
    std::unordered_map<Key, size_t, Hash> leaves_;
};

struct Placement {
    glm::dmat3 world_to_index;  // the inverse of (member transform) x (grid's index to world), linear part
    glm::dvec3 world_origin;    // the world point of index (0, 0, 0)
    glm::dvec3 world_min, world_max;
    double voxel = 0.0;         // the grid's voxel in the world (the longest of its axes)
};

Placement place(const protocol::DensityVolume& member, const volume::DensityGrid& grid) {
    const auto& m = grid.index_to_world;
    const glm::dmat3 index_linear(glm::dvec3(m[0], m[4], m[8]), glm::dvec3(m[1], m[5], m[9]), glm::dvec3(m[2], m[6], m[10]));
    const glm::dvec3 index_offset(m[3], m[7], m[11]);
    const glm::dmat3 turn = mesh::rotation({member.rotation_deg[0], member.rotation_deg[1], member.rotation_deg[2]}) * member.scale;
    const glm::dvec3 position(member.position[0], member.position[1], member.position[2]);
    Placement p;
    const glm::dmat3 linear = turn * index_linear;
    p.world_origin = turn * index_offset + position;
    p.world_to_index = glm::inverse(linear);
    p.voxel = std::max({glm::length(linear[0]), glm::length(linear[1]), glm::length(linear[2])});
    // The world box of the leaves' index box (half a voxel around their outermost centres).
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const volume::DensityLeaf& leaf : grid.leaves) {
        const glm::dvec3 o(leaf.origin[0], leaf.origin[1], leaf.origin[2]);
        lo = glm::min(lo, o - 0.5);
        hi = glm::max(hi, o + 7.5);
    }
    p.world_min = glm::dvec3(std::numeric_limits<double>::infinity());
    p.world_max = -p.world_min;
    for (int corner = 0; corner < 8 && !grid.leaves.empty(); ++corner) {
        const glm::dvec3 index((corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y, (corner & 4) ? hi.z : lo.z);
        const glm::dvec3 world = linear * index + p.world_origin;
        p.world_min = glm::min(p.world_min, world);
        p.world_max = glm::max(p.world_max, world);
    }
    return p;
}

glm::dvec3 vec(const protocol::Vec3& v) {
    return {v[0], v[1], v[2]};
}

// Evaluates one member's grid over field voxels: value(the grid's trilinear value) averaged over 1 or 2^3
// points of the voxel (2^3 where the grid's voxel is smaller than the field's).
class MemberSampler {
public:
    MemberSampler(const passes::GridGeometry& lattice, uint32_t step, const protocol::DensityVolume& member,
                  const volume::DensityGrid& grid)
        : p_(place(member, grid)),
          lookup_(grid),
          side_(static_cast<double>(lattice.voxel_size) * step),
          origin_(lattice.origin),
          samples_(static_cast<int>(std::clamp(std::ceil(side_ / p_.voxel), 1.0, 2.0))),
          empty_(grid.leaves.empty()) {}

    // Whether field voxel v may hold anything of the grid (its box in the voxel's).
    bool reaches(glm::ivec3 v) const {
        const glm::dvec3 lo = origin_ + glm::dvec3(v) * side_, hi = lo + side_;
        return !empty_ && glm::all(glm::lessThanEqual(lo, p_.world_max)) && glm::all(glm::greaterThanEqual(hi, p_.world_min));
    }

    template <class Value>
    glm::dvec3 mean(glm::ivec3 v, Value value) const {
        glm::dvec3 sum(0.0);
        for (int s = 0; s < samples_ * samples_ * samples_; ++s) {
            const glm::dvec3 sub((s % samples_ + 0.5) / samples_, (s / samples_ % samples_ + 0.5) / samples_,
                                 (s / samples_ / samples_ + 0.5) / samples_);
            const glm::dvec3 world = origin_ + (glm::dvec3(v) + sub) * side_;
            sum += value(lookup_.trilinear(p_.world_to_index * (world - p_.world_origin)));
        }
        return sum / static_cast<double>(samples_ * samples_ * samples_);
    }

private:
    Placement p_;
    DensityLookup lookup_;
    double side_;
    glm::dvec3 origin_;
    int samples_;
    bool empty_;
};

glm::ivec3 extent(vk::Extent3 e) {
    return {static_cast<int>(e.x), static_cast<int>(e.y), static_cast<int>(e.z)};
}

size_t linear(glm::ivec3 v, glm::ivec3 dims) {
    return (static_cast<size_t>(v.z) * static_cast<size_t>(dims.y) + static_cast<size_t>(v.y)) * static_cast<size_t>(dims.x) +
           static_cast<size_t>(v.x);
}

// The world boxes where each grid of the volumes may be non-zero: per leaf, its voxels and the voxel
// around them a trilinear fetch reaches, through the grid's transform and the member's.
std::vector<std::pair<glm::dvec3, glm::dvec3>> leaf_boxes(const std::map<std::string, protocol::DensityVolume>& volumes,
                                                          const Densities& densities) {
    std::vector<std::pair<glm::dvec3, glm::dvec3>> boxes;
    for (const auto& [name, member] : volumes) {
        const auto it = densities.find(name);
        if (it == densities.end()) continue;
        for (const auto& grid : {it->second.density, member.emission.emits() ? it->second.emission : nullptr}) {
            if (!grid || grid->leaves.empty()) continue;
            const Placement p = place(member, *grid);
            const glm::dmat3 index_to_world = glm::inverse(p.world_to_index);
            for (const volume::DensityLeaf& leaf : grid->leaves) {
                const glm::dvec3 o(leaf.origin[0], leaf.origin[1], leaf.origin[2]);
                glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
                for (int corner = 0; corner < 8; ++corner) {
                    const glm::dvec3 index = o + glm::dvec3((corner & 1) ? 8.0 : -1.0, (corner & 2) ? 8.0 : -1.0, (corner & 4) ? 8.0 : -1.0);
                    const glm::dvec3 world = index_to_world * index + p.world_origin;
                    lo = glm::min(lo, world);
                    hi = glm::max(hi, world);
                }
                boxes.emplace_back(lo, hi);
            }
        }
    }
    return boxes;
}

// Whether each block of a field of `step` holds a brick: it, or the voxel around it, may be non-zero.
std::vector<bool> reached_blocks(const passes::GridGeometry& lattice, uint32_t step,
                                 const std::vector<std::pair<glm::dvec3, glm::dvec3>>& boxes, uint32_t& count) {
    const glm::ivec3 dims = extent(lattice.coarsened(step));
    const glm::ivec3 blocks = (dims + static_cast<int>(kMediumFieldBlock) - 1) / static_cast<int>(kMediumFieldBlock);
    std::vector<bool> reached(static_cast<size_t>(blocks.x) * static_cast<size_t>(blocks.y) * static_cast<size_t>(blocks.z), false);
    const double side = static_cast<double>(lattice.voxel_size) * step;
    const glm::dvec3 origin(lattice.origin);
    count = 0;
    for (const auto& [lo, hi] : boxes) {
        // Clamped as doubles: a box kilometres away is no integer.
        const glm::dvec3 top(dims - 1);
        const glm::ivec3 first(glm::clamp(glm::floor((lo - origin) / side) - 1.0, glm::dvec3(0.0), top));
        const glm::ivec3 last(glm::clamp(glm::floor((hi - origin) / side) + 1.0, glm::dvec3(0.0), top));
        if (glm::any(glm::lessThan((hi - origin) / side, glm::dvec3(-1.0))) || glm::any(glm::greaterThan((lo - origin) / side, glm::dvec3(dims) + 1.0)))
            continue;
        const glm::ivec3 b0 = first / static_cast<int>(kMediumFieldBlock), b1 = last / static_cast<int>(kMediumFieldBlock);
        for (int z = b0.z; z <= b1.z; ++z)
            for (int y = b0.y; y <= b1.y; ++y)
                for (int x = b0.x; x <= b1.x; ++x) {
                    const size_t i = linear({x, y, z}, blocks);
                    if (!reached[i]) ++count;
                    reached[i] = true;
                }
    }
    return reached;
}

vk::Extent3 atlas_bricks(uint32_t count) {
    const uint32_t n = std::max(count, 1u), row = kMediumAtlasBricks;
    return {std::min(n, row), std::min((n + row - 1) / row, row), (n + row * row - 1) / (row * row)};
}

// The mark of a block that emits but does not extinguish: a trace of extinction (per metre) that no
// ray notices but that says the block is not empty.
constexpr float kEmittingBlockMark = 1e-20f;

// The emitters' table, the emitted power and the largest channel ratio from the emitting voxels.
void list_emitters(MediumField& field, const std::vector<std::pair<glm::ivec3, glm::vec4>>& emitting, const passes::GridGeometry& lattice) {
    double sum = 0.0;
    std::vector<std::pair<uint32_t, double>> voxels;
    for (const auto& [v, e] : emitting) {
        const double mean = (static_cast<double>(e.r) + static_cast<double>(e.g) + static_cast<double>(e.b)) / 3.0;
        if (!(mean > 0.0)) continue;
        sum += mean;
        voxels.emplace_back(static_cast<uint32_t>(v.x) | static_cast<uint32_t>(v.y) << MEDIUM_VOXEL_BITS |
                                static_cast<uint32_t>(v.z) << (2 * MEDIUM_VOXEL_BITS),
                            sum);
        field.emitted.channel_ratio = std::max(field.emitted.channel_ratio, static_cast<double>(std::max({e.r, e.g, e.b})) / mean);
    }
    field.emitters.reserve(voxels.size());
    for (const auto& [voxel, cumulative] : voxels)
        field.emitters.emplace_back(voxel, std::bit_cast<uint32_t>(static_cast<float>(cumulative / sum)));
    if (!field.emitters.empty()) field.emitters.back().y = std::bit_cast<uint32_t>(1.0f);
    const double side = static_cast<double>(lattice.voxel_size) * field.layout.step;
    field.emitted.power = 4.0 * std::numbers::pi * sum * side * side * side;
}

// Each reached block's own voxels, in the order the blocks come (slot_of: a block's place among them).
struct Interiors {
    glm::ivec3 dims, blocks;  // the field's voxels and blocks
    std::vector<uint32_t> slot_of;
    std::vector<glm::ivec3> block_of;
    std::vector<glm::vec4> extinction, scattering, emission;
};

constexpr size_t kBlockVoxels = size_t{kMediumFieldBlock} * kMediumFieldBlock * kMediumFieldBlock;

// Marks each block of the map without a brick with the largest empty span it lies in: in its majorant's
// place, k where the aligned cube of 2^k x 2^k x 2^k blocks around it holds no brick (blocks past the
// field's faces hold none), so that a ray crosses that cube in one step, as an octree leaf of clear
// space is crossed (field_step). A pyramid of occupancy, one level per k.
void mark_empty_spans(std::vector<glm::uvec2>& map, glm::ivec3 blocks) {
    std::vector<bool> occupied(map.size());
    for (size_t i = 0; i < map.size(); ++i) occupied[i] = map[i].x != MEDIUM_NO_BRICK;
    glm::ivec3 cells = blocks;
    for (uint32_t k = 1; glm::any(glm::greaterThan(cells, glm::ivec3(1))); ++k) {
        const glm::ivec3 parents = (cells + 1) / 2;
        std::vector<bool> above(static_cast<size_t>(parents.x) * static_cast<size_t>(parents.y) * static_cast<size_t>(parents.z), false);
        for (int z = 0; z < cells.z; ++z)
            for (int y = 0; y < cells.y; ++y)
                for (int x = 0; x < cells.x; ++x)
                    if (occupied[linear({x, y, z}, cells)]) above[linear(glm::ivec3(x, y, z) / 2, parents)] = true;
        for (int z = 0; z < blocks.z; ++z)
            for (int y = 0; y < blocks.y; ++y)
                for (int x = 0; x < blocks.x; ++x) {
                    glm::uvec2& block = map[linear({x, y, z}, blocks)];
                    if (block.x == MEDIUM_NO_BRICK && block.y == k - 1 && !above[linear(glm::ivec3(x, y, z) >> static_cast<int>(k), parents)])
                        block.y = k;
                }
        occupied = std::move(above);
        cells = parents;
    }
}

// The bricks of `in` into `field` (its atlases and map of blocks), and the voxels that emit.
std::vector<std::pair<glm::ivec3, glm::vec4>> lay_bricks(MediumField& field, const Interiors& in) {
    const glm::ivec3 dims = in.dims, blocks = in.blocks;
    const int block = static_cast<int>(kMediumFieldBlock);
    const bool volumes_emit = field.layout.emits;
    // Bricks: each kept block and the voxel around it (a neighbour's, 0 where none is kept, the edge's
    // own beyond the field's faces, as a clamped texture would give). A block whose brick holds nothing
    // keeps none.
    auto voxel_value = [&](const std::vector<glm::vec4>& values, glm::ivec3 v) {
        v = glm::clamp(v, glm::ivec3(0), dims - 1);
        const uint32_t slot = in.slot_of[linear(v / block, blocks)];
        if (slot == MEDIUM_NO_BRICK) return glm::vec4(0.0f);
        const glm::ivec3 local = v - v / block * block;
        return values[slot * kBlockVoxels + static_cast<size_t>((local.z * 8 + local.y) * 8 + local.x)];
    };
    constexpr int kSide = static_cast<int>(kMediumBrickSide);
    struct Brick {
        std::vector<glm::vec4> extinction, scattering, emission;
        float majorant = 0.0f;
    };
    std::vector<std::pair<size_t, Brick>> kept;  // by block index
    std::vector<std::pair<glm::ivec3, glm::vec4>> emitting;
    for (size_t b = 0; b < in.block_of.size(); ++b) {
        Brick brick;
        bool any = false, brick_emits = false;
        for (int t = 0; t < kSide * kSide * kSide; ++t) {
            const glm::ivec3 v = in.block_of[b] * block - 1 + glm::ivec3(t % kSide, t / kSide % kSide, t / kSide / kSide);
            const glm::vec4 e = voxel_value(in.extinction, v), s = voxel_value(in.scattering, v);
            const glm::vec4 l = volumes_emit ? voxel_value(in.emission, v) : glm::vec4(0.0f);
            brick.extinction.push_back(e);
            brick.scattering.push_back(s);
            if (volumes_emit) brick.emission.push_back(l);
            brick.majorant = std::max({brick.majorant, e.r, e.g, e.b});
            any = any || e != glm::vec4(0.0f) || s != glm::vec4(0.0f) || l != glm::vec4(0.0f);
            brick_emits = brick_emits || l != glm::vec4(0.0f);
        }
        if (brick_emits) brick.majorant = std::max(brick.majorant, kEmittingBlockMark);
        if (!any) continue;
        if (brick_emits)
            for (size_t k = 0; k < kBlockVoxels; ++k) {
                const glm::ivec3 v = in.block_of[b] * block + glm::ivec3(static_cast<int>(k % 8), static_cast<int>(k / 8 % 8), static_cast<int>(k / 64));
                if (glm::all(glm::lessThan(v, dims)) && in.emission[b * kBlockVoxels + k] != glm::vec4(0.0f))
                    emitting.emplace_back(v, in.emission[b * kBlockVoxels + k]);
            }
        kept.emplace_back(linear(in.block_of[b], blocks), std::move(brick));
    }

    // The atlases, and the map of blocks to their bricks.
    field.layout.brick_count = static_cast<uint32_t>(kept.size());
    field.layout.bricks = atlas_bricks(field.layout.brick_count);
    const glm::ivec3 atlas = extent(field.layout.bricks) * kSide;
    const size_t texels = static_cast<size_t>(atlas.x) * static_cast<size_t>(atlas.y) * static_cast<size_t>(atlas.z);
    field.extinction.assign(texels, glm::vec4(0.0f));
    field.scattering.assign(texels, glm::vec4(0.0f));
    if (volumes_emit) field.emission.assign(texels, glm::vec4(0.0f));
    field.blocks.assign(static_cast<size_t>(blocks.x) * static_cast<size_t>(blocks.y) * static_cast<size_t>(blocks.z),
                        glm::uvec2(MEDIUM_NO_BRICK, 0u));
    const glm::ivec3 row = extent(field.layout.bricks);
    for (size_t k = 0; k < kept.size(); ++k) {
        const auto& [index, brick] = kept[k];
        field.blocks[index] = glm::uvec2(static_cast<uint32_t>(k), std::bit_cast<uint32_t>(brick.majorant));
        const int slot = static_cast<int>(k);
        const glm::ivec3 corner = glm::ivec3(slot % row.x, slot / row.x % row.y, slot / row.x / row.y) * kSide;
        for (int t = 0; t < kSide * kSide * kSide; ++t) {
            const size_t at = linear(corner + glm::ivec3(t % kSide, t / kSide % kSide, t / kSide / kSide), atlas);
            field.extinction[at] = brick.extinction[static_cast<size_t>(t)];
            field.scattering[at] = brick.scattering[static_cast<size_t>(t)];
            if (volumes_emit) field.emission[at] = brick.emission[static_cast<size_t>(t)];
        }
    }
    mark_empty_spans(field.blocks, blocks);
    return emitting;
}

// The layout of the field (plan_medium_field) and which of its blocks the volumes reach.
struct Plan {
    MediumFieldLayout layout;
    std::vector<bool> reached{false};
};

Plan plan(const passes::GridGeometry& lattice, const std::map<std::string, protocol::DensityVolume>& volumes,
          const Densities& densities) {
    Plan planned;
    MediumFieldLayout& layout = planned.layout;
    if (volumes.empty()) return planned;
    layout.emits = std::any_of(volumes.begin(), volumes.end(), [](const auto& named) { return named.second.emission.emits(); });
    const auto boxes = leaf_boxes(volumes, densities);
    for (;; ++layout.step) {
        planned.reached = reached_blocks(lattice, layout.step, boxes, layout.brick_count);
        if (layout.brick_count <= kMaxMediumBricks) break;
    }
    layout.dims = lattice.coarsened(layout.step);
    layout.bricks = atlas_bricks(layout.brick_count);
    return planned;
}

}  // namespace

bool volume_world_box(const protocol::DensityVolume& member, const volume::DensityGrid& grid, glm::dvec3& lo, glm::dvec3& hi) {
    if (grid.leaves.empty()) return false;
    const Placement p = place(member, grid);
    lo = p.world_min;
    hi = p.world_max;
    return true;
}

MediumFieldLayout plan_medium_field(const passes::GridGeometry& lattice,
                                    const std::map<std::string, protocol::DensityVolume>& volumes, const Densities& densities) {
    return plan(lattice, volumes, densities).layout;
}

uint64_t medium_field_bytes(const MediumFieldLayout& layout) {
    const uint64_t brick_texels = uint64_t{kMediumBrickSide} * kMediumBrickSide * kMediumBrickSide;
    const uint64_t texels = uint64_t{layout.bricks.x} * layout.bricks.y * layout.bricks.z * brick_texels;
    const uint64_t block = kMediumFieldBlock;
    const uint64_t blocks = (layout.dims.x + block - 1) / block * ((layout.dims.y + block - 1) / block) * ((layout.dims.z + block - 1) / block);
    return texels * sizeof(glm::vec4) * (layout.emits ? 3 : 2) + blocks * sizeof(glm::uvec2) +
           (layout.emits ? uint64_t{layout.brick_count} * kMediumFieldBlock * kMediumFieldBlock * kMediumFieldBlock * sizeof(glm::uvec2) : 0);
}

MediumField resample_volumes(const passes::GridGeometry& lattice,
                             const std::map<std::string, protocol::DensityVolume>& volumes, const Densities& densities) {
    MediumField field;
    for (const auto& [name, member] : volumes) {
        const auto it = densities.find(name);
        if (it == densities.end() || !it->second.density)
            throw RenderError("volume '" + member.asset + "' of /volumes/" + name + " is not loaded");
        if (member.emission.emits() && !it->second.emission)
            throw RenderError("grid '" + member.emission_grid() + "' of volume '" + member.asset + "' (/volumes/" + name +
                              "/emission) is not loaded");
    }
    Plan planned = plan(lattice, volumes, densities);
    field.layout = planned.layout;
    const MediumFieldLayout& layout = field.layout;
    const glm::ivec3 dims = extent(layout.dims);
    const int block = static_cast<int>(kMediumFieldBlock);
    const glm::ivec3 blocks = (dims + block - 1) / block;
    const std::vector<bool>& reached = planned.reached;

    std::vector<uint32_t> slot_of(reached.size(), MEDIUM_NO_BRICK);
    std::vector<glm::ivec3> block_of;
    for (size_t i = 0; i < reached.size(); ++i)
        if (reached[i]) {
            slot_of[i] = static_cast<uint32_t>(block_of.size());
            block_of.emplace_back(static_cast<int>(i % static_cast<size_t>(blocks.x)),
                                  static_cast<int>(i / static_cast<size_t>(blocks.x) % static_cast<size_t>(blocks.y)),
                                  static_cast<int>(i / static_cast<size_t>(blocks.x) / static_cast<size_t>(blocks.y)));
        }
    std::vector<glm::vec4> extinction(block_of.size() * kBlockVoxels, glm::vec4(0.0f));
    std::vector<glm::vec4> scattering(extinction.size(), glm::vec4(0.0f));
    std::vector<glm::vec4> emission(layout.emits ? extinction.size() : 0, glm::vec4(0.0f));
    auto each_voxel = [&](const MemberSampler& sampler, auto visit) {
        for (size_t b = 0; b < block_of.size(); ++b)
            for (size_t k = 0; k < kBlockVoxels; ++k) {
                const glm::ivec3 v = block_of[b] * block + glm::ivec3(static_cast<int>(k % 8), static_cast<int>(k / 8 % 8), static_cast<int>(k / 64));
                if (glm::all(glm::lessThan(v, dims)) && sampler.reaches(v)) visit(b * kBlockVoxels + k, v);
            }
    };
    for (const auto& [name, member] : volumes) {
        const VolumeGrids& grids = densities.at(name);
        const glm::dvec3 ext = vec(member.extinction) * member.density_scale;
        const glm::dvec3 sca = vec(member.scattering) * member.density_scale;
        const double g = member.phase.model == protocol::PhaseModel::isotropic ? 0.0 : member.phase.g;
        const double g_weight = g * (sca.x + sca.y + sca.z) / 3.0;
        const MemberSampler density(lattice, layout.step, member, *grids.density);
        each_voxel(density, [&](size_t i, glm::ivec3 v) {
            const double d = density.mean(v, [](double value) { return glm::dvec3(value); }).x;
            extinction[i] += glm::vec4(glm::vec3(ext * d), 0.0f);
            scattering[i] += glm::vec4(glm::vec3(sca * d), static_cast<float>(g_weight * d));
        });
        if (!member.emission.emits()) continue;
        const bool blackbody = !member.emission.temperature_grid.empty();
        const glm::dvec3 colour = vec(member.emission.color) * member.emission.intensity;
        const double intensity = member.emission.intensity;
        const MemberSampler emitted(lattice, layout.step, member, *grids.emission);
        each_voxel(emitted, [&](size_t i, glm::ivec3 v) {
            emission[i] += glm::vec4(glm::vec3(emitted.mean(v, [&](double value) {
                return blackbody ? blackbody_rgb(value) * intensity : colour * value;
            })), 0.0f);
        });
    }

    Interiors interiors{dims, blocks, std::move(slot_of), std::move(block_of), std::move(extinction), std::move(scattering),
                        std::move(emission)};
    const auto emitting = lay_bricks(field, interiors);
    list_emitters(field, emitting, lattice);
    if (field.emitters.empty()) {
        field.emission.clear();  // emits nothing after all
        field.layout.emits = false;
    }
    return field;
}

}  // namespace refract::scene
