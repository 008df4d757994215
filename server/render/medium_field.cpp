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

// Calls add(i, mean) for each field voxel i that the member's `grid` reaches where the mean over 1 or
// 2^3 points in the voxel (2^3 where the grid's voxel is smaller than the field's) of value(the grid's
// trilinear value there) is not 0.
template <class Value, class Add>
void sample_grid(const MediumField& field, const passes::GridGeometry& lattice, uint32_t step,
                 const protocol::DensityVolume& member, const volume::DensityGrid& grid, Value value, Add add) {
    if (grid.leaves.empty()) return;
    const Placement p = place(member, grid);
    const double side = static_cast<double>(lattice.voxel_size) * step;  // a field voxel, metres
    const glm::dvec3 origin(lattice.origin);
    const glm::ivec3 dims(static_cast<int>(field.dims.x), static_cast<int>(field.dims.y), static_cast<int>(field.dims.z));
    // Clamped as doubles: a box kilometres away is no integer.
    const glm::dvec3 top(dims);
    const glm::ivec3 first(glm::clamp(glm::floor((p.world_min - origin) / side), glm::dvec3(0.0), top));
    const glm::ivec3 end(glm::clamp(glm::floor((p.world_max - origin) / side) + 1.0, glm::dvec3(0.0), top));
    const int samples = static_cast<int>(std::clamp(std::ceil(side / p.voxel), 1.0, 2.0));
    const DensityLookup lookup(grid);
    for (int z = first.z; z < end.z; ++z)
        for (int y = first.y; y < end.y; ++y)
            for (int x = first.x; x < end.x; ++x) {
                glm::dvec3 sum(0.0);
                for (int s = 0; s < samples * samples * samples; ++s) {
                    const glm::dvec3 sub((s % samples + 0.5) / samples, (s / samples % samples + 0.5) / samples,
                                         (s / samples / samples + 0.5) / samples);
                    const glm::dvec3 world = origin + (glm::dvec3(x, y, z) + sub) * side;
                    sum += value(lookup.trilinear(p.world_to_index * (world - p.world_origin)));
                }
                if (sum == glm::dvec3(0.0)) continue;
                add((static_cast<size_t>(z) * field.dims.y + static_cast<size_t>(y)) * field.dims.x + static_cast<size_t>(x),
                    sum / static_cast<double>(samples * samples * samples));
            }
}

// Adds one volume's coefficients to `field` over the field voxels its box meets.
void add_volume(MediumField& field, const passes::GridGeometry& lattice, uint32_t step,
                const protocol::DensityVolume& member, const volume::DensityGrid& grid) {
    const glm::dvec3 extinction = vec(member.extinction) * member.density_scale;
    const glm::dvec3 scattering = vec(member.scattering) * member.density_scale;
    const double g = member.phase.model == protocol::PhaseModel::isotropic ? 0.0 : member.phase.g;
    const double g_weight = g * (scattering.x + scattering.y + scattering.z) / 3.0;
    sample_grid(field, lattice, step, member, grid, [](double density) { return glm::dvec3(density); },
                [&](size_t i, glm::dvec3 mean) {
                    const double density = mean.x;
                    field.extinction[i] += glm::vec4(glm::vec3(extinction * density), 0.0f);
                    field.scattering[i] += glm::vec4(glm::vec3(scattering * density), static_cast<float>(g_weight * density));
                });
}

// Adds what one volume emits to `field.emission`: from its temperature grid through blackbody_rgb, or
// its colour times its emission grid's value.
void add_emission(MediumField& field, const passes::GridGeometry& lattice, uint32_t step,
                  const protocol::DensityVolume& member, const volume::DensityGrid& grid) {
    const bool blackbody = !member.emission.temperature_grid.empty();
    const glm::dvec3 colour = vec(member.emission.color) * member.emission.intensity;
    const double intensity = member.emission.intensity;
    sample_grid(field, lattice, step, member, grid,
                [&](double value) { return blackbody ? blackbody_rgb(value) * intensity : colour * value; },
                [&](size_t i, glm::dvec3 mean) { field.emission[i] += glm::vec4(glm::vec3(mean), 0.0f); });
}

// The emitters' table, the emitted power and the largest channel ratio from field.emission.
void list_emitters(MediumField& field, const passes::GridGeometry& lattice, uint32_t step) {
    double sum = 0.0;
    std::vector<std::pair<uint32_t, double>> voxels;
    for (size_t i = 0; i < field.emission.size(); ++i) {
        const glm::vec4& e = field.emission[i];
        const double mean = (static_cast<double>(e.r) + static_cast<double>(e.g) + static_cast<double>(e.b)) / 3.0;
        if (!(mean > 0.0)) continue;
        sum += mean;
        voxels.emplace_back(static_cast<uint32_t>(i), sum);
        field.emitted.channel_ratio = std::max(field.emitted.channel_ratio, static_cast<double>(std::max({e.r, e.g, e.b})) / mean);
    }
    field.emitters.reserve(voxels.size());
    for (const auto& [voxel, cumulative] : voxels)
        field.emitters.emplace_back(voxel, std::bit_cast<uint32_t>(static_cast<float>(cumulative / sum)));
    if (!field.emitters.empty()) field.emitters.back().y = std::bit_cast<uint32_t>(1.0f);
    const double side = static_cast<double>(lattice.voxel_size) * step;
    field.emitted.power = 4.0 * std::numbers::pi * sum * side * side * side;
}

}  // namespace

bool volume_world_box(const protocol::DensityVolume& member, const volume::DensityGrid& grid, glm::dvec3& lo, glm::dvec3& hi) {
    if (grid.leaves.empty()) return false;
    const Placement p = place(member, grid);
    lo = p.world_min;
    hi = p.world_max;
    return true;
}

uint32_t medium_field_step(const passes::GridGeometry& lattice) {
    uint32_t step = 1;
    while (lattice.coarsened(step).count() > kMaxMediumFieldVoxels) ++step;
    return step;
}

uint64_t medium_field_bytes(const passes::GridGeometry& lattice, bool volumes, bool emits) {
    if (!volumes) return 0;
    const uint64_t voxels = lattice.coarsened(medium_field_step(lattice)).count();
    return voxels * 2 * sizeof(glm::vec4) + (emits ? voxels * (sizeof(glm::vec4) + sizeof(glm::uvec2)) : 0);
}

namespace {

// Each voxel's extinction w: the most extinction (any channel) over its block of kMediumFieldBlock^3
// field voxels and the voxels around the block, which a trilinear fetch in it reaches: 0 where the
// field is 0 throughout the block.
// The mark of a block that emits but does not extinguish: a trace of extinction (per metre) that no
// ray notices but that says the block is not empty.
constexpr float kEmittingBlockMark = 1e-20f;

void mark_blocks(MediumField& field) {
    const glm::ivec3 dims(static_cast<int>(field.dims.x), static_cast<int>(field.dims.y), static_cast<int>(field.dims.z));
    auto at = [&](glm::ivec3 v) {
        return (static_cast<size_t>(v.z) * field.dims.y + static_cast<size_t>(v.y)) * field.dims.x + static_cast<size_t>(v.x);
    };
    const int side = static_cast<int>(kMediumFieldBlock);
    for (int bz = 0; bz < dims.z; bz += side)
        for (int by = 0; by < dims.y; by += side)
            for (int bx = 0; bx < dims.x; bx += side) {
                const glm::ivec3 block(bx, by, bz);
                const glm::ivec3 lo = glm::max(block - 1, glm::ivec3(0)), hi = glm::min(block + side + 1, dims);
                float most = 0.0f;
                for (int z = lo.z; z < hi.z; ++z)
                    for (int y = lo.y; y < hi.y; ++y)
                        for (int x = lo.x; x < hi.x; ++x) {
                            const glm::vec4& e = field.extinction[at({x, y, z})];
                            most = std::max({most, e.r, e.g, e.b});
                            // A block that only emits is crossed in field voxels too, as what it
                            // emits is gathered step by step.
                            if (!field.emission.empty() && field.emission[at({x, y, z})] != glm::vec4(0.0f))
                                most = std::max(most, kEmittingBlockMark);
                        }
                const glm::ivec3 end = glm::min(block + side, dims);
                for (int z = bz; z < end.z; ++z)
                    for (int y = by; y < end.y; ++y)
                        for (int x = bx; x < end.x; ++x) field.extinction[at({x, y, z})].w = most;
            }
}

}  // namespace

MediumField resample_volumes(const passes::GridGeometry& lattice,
                             const std::map<std::string, protocol::DensityVolume>& volumes, const Densities& densities) {
    MediumField field;
    if (!volumes.empty()) field.dims = lattice.coarsened(medium_field_step(lattice));
    field.extinction.assign(field.dims.count(), glm::vec4(0.0f));
    field.scattering.assign(field.dims.count(), glm::vec4(0.0f));
    const uint32_t step = medium_field_step(lattice);
    for (const auto& [name, member] : volumes) {
        const auto it = densities.find(name);
        if (it == densities.end() || !it->second.density)
            throw RenderError("volume '" + member.asset + "' of /volumes/" + name + " is not loaded");
        add_volume(field, lattice, step, member, *it->second.density);
        if (!member.emission.emits()) continue;
        if (!it->second.emission)
            throw RenderError("grid '" + member.emission_grid() + "' of volume '" + member.asset + "' (/volumes/" + name +
                              "/emission) is not loaded");
        if (field.emission.empty()) field.emission.assign(field.dims.count(), glm::vec4(0.0f));
        add_emission(field, lattice, step, member, *it->second.emission);
    }
    mark_blocks(field);
    list_emitters(field, lattice, step);
    if (field.emitters.empty()) field.emission.clear();  // emits nothing after all: one texel of zeros
    return field;
}

}  // namespace refract::scene
