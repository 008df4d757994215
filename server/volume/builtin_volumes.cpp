#include "volume/builtin_volumes.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <mutex>

namespace refract::volume {

namespace {

// Value noise in [0, 1): hashed lattice values, smoothly interpolated; fbm sums three octaves.
float lattice(int x, int y, int z) {
    uint32_t h = static_cast<uint32_t>(x) * 73856093u ^ static_cast<uint32_t>(y) * 19349663u ^ static_cast<uint32_t>(z) * 83492791u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return static_cast<float>(h & 0xffffffu) / 16777216.0f;
}

float noise(float x, float y, float z) {
    const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y)), iz = static_cast<int>(std::floor(z));
    auto smooth = [](float t) { return t * t * (3.0f - 2.0f * t); };
    const float fx = smooth(x - static_cast<float>(ix)), fy = smooth(y - static_cast<float>(iy)), fz = smooth(z - static_cast<float>(iz));
    float sum = 0.0f;
    for (int c = 0; c < 8; ++c) {
        const int ox = c & 1, oy = (c >> 1) & 1, oz = (c >> 2) & 1;
        sum += (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz) * lattice(ix + ox, iy + oy, iz + oz);
    }
    return sum;
}

float fbm(float x, float y, float z) {
    return 0.5f * noise(x, y, z) + 0.3f * noise(2.03f * x, 2.03f * y, 2.03f * z) + 0.2f * noise(4.11f * x, 4.11f * y, 4.11f * z);
}

// A grid of `voxel` metres over index box [lo, hi] (inclusive, whole leaves), value f(world point) where
// above 1e-3, inactive elsewhere.
DensityGrid sampled(double voxel, std::array<int, 3> lo, std::array<int, 3> hi, const std::function<float(float, float, float)>& f) {
    DensityGrid grid;
    grid.index_to_world = {voxel, 0, 0, 0, 0, voxel, 0, 0, 0, 0, voxel, 0};
    for (int ox = lo[0] & ~7; ox <= hi[0]; ox += kLeafSide)
        for (int oy = lo[1] & ~7; oy <= hi[1]; oy += kLeafSide)
            for (int oz = lo[2] & ~7; oz <= hi[2]; oz += kLeafSide) {
                DensityLeaf leaf;
                leaf.origin = {ox, oy, oz};
                bool any = false;
                for (int x = 0; x < kLeafSide; ++x)
                    for (int y = 0; y < kLeafSide; ++y)
                        for (int z = 0; z < kLeafSide; ++z) {
                            const float v = f(static_cast<float>((ox + x) * voxel), static_cast<float>((oy + y) * voxel),
                                              static_cast<float>((oz + z) * voxel));
                            if (!(v > 1e-3f)) continue;
                            leaf.values[static_cast<size_t>((x * 8 + y) * 8 + z)] = v;
                            any = true;
                        }
                if (any) grid.leaves.push_back(leaf);
            }
    return grid;
}

float clamp01(float v) { return std::clamp(v, 0.0f, 1.0f); }

// Cumulus: overlapping puffs on a flat base, each edge eaten into by noise.
float cloud(float x, float y, float z) {
    struct Puff { float x, y, z, r; };
    static constexpr Puff kPuffs[] = {{0.0f, 0.45f, 0.0f, 0.5f},   {-0.55f, 0.35f, 0.1f, 0.38f}, {0.6f, 0.33f, -0.05f, 0.4f},
                                      {0.2f, 0.75f, 0.1f, 0.35f},  {-0.25f, 0.7f, -0.15f, 0.3f}, {0.95f, 0.25f, 0.2f, 0.25f},
                                      {-0.9f, 0.25f, -0.1f, 0.25f}, {0.1f, 0.35f, 0.45f, 0.33f}, {-0.1f, 0.35f, -0.45f, 0.3f}};
    float shape = -1.0f;  // far from every puff
    for (const Puff& p : kPuffs) {
        const float d = std::sqrt((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y) + (z - p.z) * (z - p.z)) / p.r;
        shape = std::max(shape, 1.0f - d);
    }
    const float base = clamp01(y / 0.12f);  // a flat underside
    if (shape <= -0.175f || base == 0.0f) return 0.0f;  // beyond what the noise can reach (+-0.175)
    return clamp01((shape + 0.35f * (fbm(3.0f * x, 3.0f * y, 3.0f * z) - 0.5f)) * 4.0f) * base;
}

// A flame: a teardrop narrowing upwards, flickering with noise; hottest low in its core.
float flame_shape(float x, float y, float z) {
    const float height = 0.5f, t = y / height;
    if (t < 0.0f || t > 1.0f) return 0.0f;
    const float radius = 0.11f * std::sqrt(t) * (1.0f - t) * 2.2f + 0.01f;
    const float wobble = 0.03f * t * (noise(4.0f * y, 1.7f, 0.3f) - 0.5f);
    const float r = std::sqrt((x - wobble) * (x - wobble) + z * z) / radius;
    if (r >= 1.0f) return 0.0f;
    return clamp01((1.0f - r) * 2.0f) * (0.75f + 0.25f * fbm(12.0f * x, 12.0f * y - 3.0f, 12.0f * z));
}

float flame_temperature(float x, float y, float z) {
    const float core = flame_shape(x, y, z);
    return core > 0.0f ? 1900.0f * std::pow(core, 0.6f) * (1.0f - 0.45f * y / 0.5f) : 0.0f;
}

float flame_soot(float x, float y, float z) { return 0.3f * flame_shape(x, y, z); }

// A plume: a column whose radius grows and density falls with height, turbulent.
float smoke(float x, float y, float z) {
    const float height = 1.2f, t = y / height;
    if (t < 0.0f || t > 1.0f) return 0.0f;
    const float sway = 0.08f * t * (noise(2.0f * y, 0.5f, 0.0f) - 0.5f) * 2.0f;
    const float radius = 0.05f + 0.2f * t;
    const float r = std::sqrt((x - sway) * (x - sway) + z * z) / radius;
    if (r >= 1.0f) return 0.0f;
    const float turbulence = fbm(6.0f * x, 6.0f * y - 2.0f, 6.0f * z);
    return clamp01(1.0f - r * r) * (1.0f - 0.7f * t) * clamp01(1.6f * turbulence - 0.15f) * clamp01(t * 12.0f);
}

struct Maker {
    const char* name;
    const char* grid;
    double voxel;
    std::array<int, 3> lo, hi;
    float (*f)(float, float, float);
};

// Index boxes cover each shape's support with a voxel to spare.
constexpr Maker kMakers[] = {
    {"builtin.cloud", "density", 0.03, {-44, -2, -32}, {44, 44, 32}, &cloud},
    {"builtin.flame", "density", 0.008, {-20, -1, -20}, {20, 64, 20}, &flame_soot},
    {"builtin.flame", "temperature", 0.008, {-20, -1, -20}, {20, 64, 20}, &flame_temperature},
    {"builtin.smoke", "density", 0.02, {-16, -1, -16}, {16, 61, 16}, &smoke},
};

GridSummary summary(const std::string& name, const DensityGrid& grid) {
    GridSummary s;
    s.name = name;
    s.type = "float";
    s.usable = true;
    s.index_min = {INT32_MAX, INT32_MAX, INT32_MAX};
    s.index_max = {INT32_MIN, INT32_MIN, INT32_MIN};
    for (const DensityLeaf& leaf : grid.leaves)
        for (size_t i = 0; i < kLeafVoxels; ++i) {
            if (leaf.values[i] == 0.0f) continue;
            ++s.active_voxels;
            const std::array<int32_t, 3> at{leaf.origin[0] + static_cast<int32_t>(i / 64), leaf.origin[1] + static_cast<int32_t>(i / 8 % 8),
                                            leaf.origin[2] + static_cast<int32_t>(i % 8)};
            for (size_t a = 0; a < 3; ++a) {
                s.index_min[a] = std::min(s.index_min[a], at[a]);
                s.index_max[a] = std::max(s.index_max[a], at[a]);
            }
        }
    const double voxel = grid.index_to_world[0];
    s.voxel_size = {voxel, voxel, voxel};
    for (size_t a = 0; a < 3; ++a) {
        s.world_min[a] = s.index_min[a] * voxel;
        s.world_max[a] = s.index_max[a] * voxel;
    }
    return s;
}

}  // namespace

const std::vector<std::string>& builtin_volume_names() {
    static const std::vector<std::string> names{"builtin.cloud", "builtin.flame", "builtin.smoke"};
    return names;
}

bool is_builtin_volume(std::string_view name) { return name.starts_with(kBuiltinVolumePrefix); }

std::shared_ptr<const DensityGrid> builtin_density(std::string_view name, std::string_view grid) {
    static std::mutex mutex;
    static std::map<std::pair<std::string, std::string>, std::shared_ptr<const DensityGrid>> made;
    for (const Maker& m : kMakers) {
        if (name != m.name || grid != m.grid) continue;
        std::lock_guard lock(mutex);
        auto& slot = made[{m.name, m.grid}];
        if (!slot) slot = std::make_shared<const DensityGrid>(sampled(m.voxel, m.lo, m.hi, m.f));
        return slot;
    }
    return nullptr;
}

std::optional<VolumeReport> builtin_volume_report(std::string_view name) {
    const auto& names = builtin_volume_names();
    if (std::find(names.begin(), names.end(), name) == names.end()) return std::nullopt;
    VolumeReport report;
    for (const Maker& m : kMakers)
        if (name == m.name) report.grids.push_back(summary(m.grid, *builtin_density(m.name, m.grid)));
    return report;
}

}  // namespace refract::volume
