// The volume passes (voxelize + smooth, index field, octree) against quantities known without them:
// mesh volumes, the Gaussian's moments, the analytic lenses and a CPU octree. Every tolerance is derived
// from the grid in the comment above its check.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "mesh/mesh.h"
#include "passes/octree.h"
#include "passes/voxelize.h"
#include "protocol/scene_document.h"
#include "render/field_atlas.h"
#include "passes/grid_geometry.h"
#include "render/invalidation.h"
#include "render/renderer.h"
#include "render/scene_gpu.h"
#include "render/scene_lattice.h"
#include "vk/commands.h"
#include "vk/resources.h"

namespace refract {
namespace {

using protocol::IndexFieldKind;
using protocol::SceneDocument;

const std::string kBunnyPath = std::string(REFRACT_SOURCE_DIR) + "/examples/meshes/bunny.obj";
// S: rays per voxel column side (S x S rays per column and axis).
constexpr double kSubsamples = static_cast<double>(passes::VoxelizePass::kSubsamples);
// Relative volume error the issue allows at 128^3.
constexpr double kVolumeSpec = 0.02;

// A document that runs only what a volume test needs (tiny frame, few photons: never run here).
SceneDocument volume_document(const std::string& mesh, uint32_t resolution, double smoothing) {
    SceneDocument d;
    d.object().mesh = mesh;
    d.volume.resolution = resolution;
    d.volume.smoothing = smoothing;
    d.image.width = 8;
    d.image.height = 8;
    d.photons.count = 64;
    return d;
}

// The volume passes' outputs read back, x fastest.
struct Volume {
    passes::GridGeometry grid;
    std::vector<float> coverage;
    std::vector<glm::vec4> field;    // n, dn/dx, dn/dy, dn/dz (per voxel length)
    std::vector<uint32_t> levels;    // octree leaf level per voxel

    size_t at(uint32_t x, uint32_t y, uint32_t z) const {
        return (size_t{z} * grid.dims.y + y) * grid.dims.x + x;
    }
    // World position of a voxel's centre, in double.
    glm::dvec3 centre(uint32_t x, uint32_t y, uint32_t z) const {
        return glm::dvec3(grid.origin) +
               (glm::dvec3(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)) + 0.5) *
                   static_cast<double>(grid.voxel_size);
    }
    double h() const { return static_cast<double>(grid.voxel_size); }
    double filled_volume() const {
        double sum = 0.0;
        for (float c : coverage) sum += static_cast<double>(c);
        return sum * h() * h() * h();
    }
    template <typename F>
    void for_each(F&& f) const {
        for (uint32_t z = 0; z < grid.dims.z; ++z)
            for (uint32_t y = 0; y < grid.dims.y; ++y)
                for (uint32_t x = 0; x < grid.dims.x; ++x) f(x, y, z, at(x, y, z));
    }
};

double surface_area(const mesh::Mesh& m) {
    double area = 0.0;
    for (const auto& t : m.triangles) {
        const glm::dvec3 a(m.positions[t.x]), b(m.positions[t.y]), c(m.positions[t.z]);
        area += 0.5 * glm::length(glm::cross(b - a, c - a));
    }
    return area;
}

// Centroid of the enclosed volume (tetrahedra from the origin).
glm::dvec3 volume_centroid(const mesh::Mesh& m) {
    glm::dvec3 moment(0.0);
    double six_volume = 0.0;
    for (const auto& t : m.triangles) {
        const glm::dvec3 a(m.positions[t.x]), b(m.positions[t.y]), c(m.positions[t.z]);
        const double v = glm::dot(a, glm::cross(b, c));
        six_volume += v;
        moment += v * (a + b + c) / 4.0;
    }
    return moment / six_volume;
}

// Worst-case relative volume error of the voxelization. Along each ray the inside length is exact; across
// the column the surface is resolved by S x S rays per voxel, i.e. to within half a ray spacing h/(2S).
// If every surface element were misplaced by that much in the same direction the volume would change by
// A h / (2S). (For an axis-aligned box this is the bound: each face's position is quantized to the ray
// grid by the two axes parallel to it and exact on the third; the mean of the three moves it 2/3 of that.)
double voxel_volume_tolerance(double area, double volume, double h, double subsamples = kSubsamples) {
    return area * h / (2.0 * subsamples) / volume;
}

std::vector<uint32_t> reference_levels(const std::vector<float>& n, vk::Extent3 dims, float epsilon, uint32_t max_level);

class VolumeTest : public testing::GpuTest {
protected:
    // The volume of `doc` with its one object's world mesh replaced by `world`.
    static Volume build(const SceneDocument& doc, const mesh::Mesh& world, bool with_octree = false,
                        uint32_t subsamples = passes::VoxelizePass::kSubsamples) {
        return build(doc, scene::WorldMeshes{{doc.objects.begin()->first, world}}, with_octree, subsamples);
    }
    static Volume build(const SceneDocument& doc, const scene::WorldMeshes& worlds, bool with_octree = false,
                        uint32_t subsamples = passes::VoxelizePass::kSubsamples) {
        scene::SceneGpu gpu(kit());
        scene::RunOptions options;
        options.limit = scene::kVoxelize | scene::kIndexField | (with_octree ? scene::kOctree : 0u);
        options.voxelize.subsamples = subsamples;
        gpu.run(scene::kAllPasses, doc, worlds, nullptr, options);
        Volume v;
        v.grid = gpu.grid();
        v.coverage = gpu.read_coverage();
        v.field = gpu.read_index_field();
        if (with_octree) v.levels = gpu.read_levels();
        return v;
    }
    static Volume build(const SceneDocument& doc, bool with_octree = false) {
        return build(doc, worlds(doc), with_octree);
    }
    // A fresh build of `doc` gives, to the bit, the volume `resident` holds after the edits that led it
    // there: index field, coverage, object numbers and octree.
    static void expect_volume_of_a_fresh_build(const scene::SceneGpu& resident, const SceneDocument& doc,
                                               const scene::RunOptions& options) {
        scene::SceneGpu fresh(kit());
        fresh.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
        EXPECT_TRUE(resident.read_index_field() == fresh.read_index_field());
        EXPECT_TRUE(resident.read_coverage() == fresh.read_coverage());
        EXPECT_TRUE(resident.read_object_numbers() == fresh.read_object_numbers());
        EXPECT_TRUE(resident.read_levels() == fresh.read_levels());
        EXPECT_TRUE(resident.read_pyramid() == fresh.read_pyramid());
    }
};

// --- Voxelized volume ------------------------------------------------------------------------------

TEST_F(VolumeTest, BuiltInShapesVoxelizeToTheirVolumeAt128) {
    struct Case {
        std::string mesh;
        double analytic;
    };
    const double torus_analytic = 2.0 * std::numbers::pi * std::numbers::pi * 1.0 * 0.35 * 0.35;  // 2 pi^2 R r^2
    const double prism_analytic = 3.0 * std::sqrt(3.0) / 4.0 * 2.0;  // triangle of circumradius 1, length 2
    for (const Case& c : {Case{"sphere", 4.0 / 3.0 * std::numbers::pi}, Case{"cube", 8.0}, Case{"torus", torus_analytic},
                          Case{"prism", prism_analytic}}) {
        SCOPED_TRACE(c.mesh);
        const SceneDocument doc = volume_document(c.mesh, 128, 0.0);
        const mesh::Mesh world = world_mesh(doc);
        const Volume v = build(doc, world);
        const double mesh_volume = mesh::signed_volume(world);
        const double tolerance = voxel_volume_tolerance(surface_area(world), mesh_volume, v.h());
        // The derived worst case stays inside the 2% at 128^3 (torus: A/V = 2/r, the tightest).
        EXPECT_LE(tolerance, kVolumeSpec);
        const double filled = v.filled_volume();
        EXPECT_NEAR(filled / mesh_volume, 1.0, tolerance) << "filled " << filled << " mesh " << mesh_volume;
        std::cout << "[ info ] " << c.mesh << ": filled/mesh - 1 = " << filled / mesh_volume - 1.0 << " (tolerance "
                  << tolerance << "), filled/analytic - 1 = " << filled / c.analytic - 1.0 << "\n";

        // Against the analytic solid, the tessellation's own deficit is added.
        double tessellation = 0.0;
        if (c.mesh == "sphere") {
            // Vertices lie on the unit sphere, so the icosphere is inscribed: its volume is at most 4/3 pi and
            // at least that of the ball of radius d_min (its closest face plane to the centre).
            double d_min = 1.0;
            for (const auto& t : world.triangles) {
                const glm::dvec3 a(world.positions[t.x]), b(world.positions[t.y]), cc(world.positions[t.z]);
                d_min = std::min(d_min, std::abs(glm::dot(glm::normalize(glm::cross(b - a, cc - a)), a)));
            }
            tessellation = 1.0 - d_min * d_min * d_min;
            EXPECT_LE(mesh_volume, c.analytic * (1.0 + 1e-6));  // 1e-6: float vertex positions
            EXPECT_GE(mesh_volume, c.analytic * (1.0 - tessellation));
        } else if (c.mesh == "torus") {
            // 96 x 48 segments: a polygon of N sides inscribed in a circle keeps sin(2pi/N) N/(2pi) of its
            // area, for the tube's cross-section and (to first order) for the ring's path.
            auto polygon = [](double n) { return std::sin(2.0 * std::numbers::pi / n) * n / (2.0 * std::numbers::pi); };
            tessellation = 1.0 - polygon(48.0) * polygon(96.0);
            EXPECT_NEAR(mesh_volume / c.analytic, 1.0, 2.0 * tessellation);
        }
        EXPECT_NEAR(filled / c.analytic, 1.0, tolerance + tessellation) << "analytic " << c.analytic;
    }
}

// A preview's voxelization (an object drag's, a load's: passes::VoxelizePass::kPreviewSubsamples rays a
// column side, on the drag's lattice of half the voxels per axis) keeps the volume within what its rays
// resolve: the same bound with S and h of that frame. Against the still's rays on the same lattice, the
// two differ by no more than their two bounds together.
TEST_F(VolumeTest, APreviewsFewerRaysVoxelizeToTheVolumeTheyResolve) {
    constexpr double kPreview = passes::VoxelizePass::kPreviewSubsamples;
    for (const std::string mesh : {"sphere", "cube", "torus", "prism"}) {
        SCOPED_TRACE(mesh);
        const SceneDocument doc = volume_document(mesh, 64, 0.0);
        const mesh::Mesh world = world_mesh(doc);
        const Volume preview = build(doc, world, false, passes::VoxelizePass::kPreviewSubsamples);
        const Volume still = build(doc, world);
        const double mesh_volume = mesh::signed_volume(world);
        const double area = surface_area(world);
        const double tolerance = voxel_volume_tolerance(area, mesh_volume, preview.h(), kPreview);
        EXPECT_NEAR(preview.filled_volume() / mesh_volume, 1.0, tolerance);
        EXPECT_NEAR(preview.filled_volume() / still.filled_volume(), 1.0,
                    tolerance + voxel_volume_tolerance(area, mesh_volume, still.h()));
        // Fewer rays: not the still's coverage (the test sees the preview's pipelines).
        EXPECT_NE(preview.coverage, still.coverage);
        std::cout << "[ info ] " << mesh << ": preview filled/mesh - 1 = " << preview.filled_volume() / mesh_volume - 1.0
                  << ", still's rays " << still.filled_volume() / mesh_volume - 1.0 << " (tolerance " << tolerance
                  << ")\n";
    }
}

TEST_F(VolumeTest, SmoothingConservesTotalCoverage) {
    // The normalized Gaussian is symmetric with weights summing to 1, so away from the clamped border the
    // sum over the grid is unchanged; so is the spline that filters the surface before it (it sums to 1
    // over the lattice at any offset, as the voxel's box does for the sharp grid, and both weigh the same
    // rays). Torus (2.7 m across) with a 0.5 m margin at 64^3: h = 3.7 m / 64, the margin is 8.6 voxels,
    // wider than the spline's 1.5 plus the lattice kernel's radius r = ceil(3 lattice_sigma) = 6: no
    // covered voxel's taps reach past the border. Rounding: each output is a float sum of 2r+1 products and a division,
    // relative error <= (2r+2) 2^-24 per pass, three passes.
    const double sigma = 2.0;
    const double radius = std::ceil(3.0 * sigma);
    SceneDocument doc = volume_document("torus", 64, 0.0);
    doc.volume.margin = 0.5;
    const Volume sharp = build(doc);
    doc.volume.smoothing = sigma;
    const Volume smooth = build(doc);
    ASSERT_EQ(sharp.grid, smooth.grid);
    const double tolerance = 3.0 * (2.0 * radius + 2.0) * std::ldexp(1.0, -24);
    EXPECT_NEAR(smooth.filled_volume() / sharp.filled_volume(), 1.0, tolerance);
    // The smoothing did something: the shell is wider (more partially covered voxels).
    auto partial = [](const Volume& v) {
        return std::count_if(v.coverage.begin(), v.coverage.end(), [](float c) { return c > 0.0f && c < 1.0f; });
    };
    EXPECT_GT(partial(smooth), 2 * partial(sharp));

    // At the border the taps clamp: the object is taken to continue beyond the grid, which is what a
    // volume.bounds that cuts through it means. A cube cut by the grid's -x face stays exactly full there
    // after smoothing (all taps read covered voxels), with no false interface at the cut. Filtering
    // reaches 1.5 voxels (the spline) plus the lattice taps, r' = ceil(3 lattice_sigma(sigma)).
    const double reach = 1.5 + std::ceil(3.0 * static_cast<double>(passes::VoxelizePass::lattice_sigma(static_cast<float>(sigma))));
    SceneDocument cut = volume_document("cube", 64, sigma);
    cut.volume.bounds = protocol::Bounds{{-0.5, -1.5, -1.5}, {2.5, 1.5, 1.5}};
    const Volume c = build(cut);
    const passes::GridGeometry& g = c.grid;
    size_t checked = 0, not_full = 0;
    c.for_each([&](uint32_t x, uint32_t y, uint32_t z, size_t i) {
        const glm::dvec3 p = c.centre(x, y, z);
        // Voxels in the cut face's layer whose filter (its reach along y and z) lies well inside.
        const double inner = 1.0 - (reach + 1.0) * c.h();
        if (x != 0 || std::abs(p.y) > inner || std::abs(p.z) > inner) return;
        ++checked;
        if (c.coverage[i] != 1.0f) ++not_full;
    });
    EXPECT_EQ(g.origin.x, -0.5f);
    EXPECT_GT(checked, 100u);
    EXPECT_EQ(not_full, 0u);
}

TEST_F(VolumeTest, GridsPastTheDispatchFoldWork) {
    // Per-voxel passes dispatch one invocation per voxel in groups of 64, folded into a second dimension
    // past 65535 groups (4,194,240 voxels, ~161^3). At 168^3 = 4.74M voxels with a 0.05 m margin
    // (4 voxels) the sphere's top cap lies beyond the fold, so a fold that skipped or repeated work would
    // lose volume there; the margin still exceeds the smoothing radius, so the volume is conserved.
    SceneDocument doc = volume_document("sphere", 168, 0.75);
    doc.volume.margin = 0.05;
    const mesh::Mesh world = world_mesh(doc);
    const Volume v = build(doc, world, true);
    ASSERT_GT(v.grid.dims.count(), uint64_t{65535} * 64);
    const double mesh_volume = mesh::signed_volume(world);
    EXPECT_NEAR(v.filled_volume() / mesh_volume, 1.0, voxel_volume_tolerance(surface_area(world), mesh_volume, v.h()));
    // The icosphere is symmetric under z -> -z: the halves of the grid hold the same coverage, to the
    // same tolerance (each half has half the area and half the volume).
    double low = 0.0, high = 0.0;
    v.for_each([&](uint32_t, uint32_t, uint32_t z, size_t i) {
        (z < v.grid.dims.z / 2 ? low : high) += static_cast<double>(v.coverage[i]);
    });
    EXPECT_NEAR(high / low, 1.0, 2.0 * voxel_volume_tolerance(surface_area(world), mesh_volume, v.h()));
    std::vector<float> n(v.field.size());
    for (size_t i = 0; i < n.size(); ++i) n[i] = v.field[i].x;
    EXPECT_EQ(v.levels, reference_levels(n, v.grid.dims, static_cast<float>(doc.volume.octree_epsilon),
                                         passes::octree_layout(v.grid.dims).max_level));
}

TEST_F(VolumeTest, InsideOutMeshFillsLikeTheOutwardOne) {
    // OBJ files from some exporters wind clockwise: the voxelizer's inside test must not depend on it.
    SceneDocument doc = volume_document("sphere", 64, 0.0);
    const mesh::Mesh outward = world_mesh(doc);
    mesh::Mesh inward = outward;
    for (auto& t : inward.triangles) std::swap(t.y, t.z);
    ASSERT_LT(mesh::signed_volume(inward), 0.0);
    const Volume a = build(doc, outward);
    const Volume b = build(doc, inward);
    ASSERT_EQ(a.grid, b.grid);
    // Same surfaces, same rays: the coverage agrees voxel for voxel up to the rounding of the crossing
    // depths (computed from the permuted vertices: a few ulps of 64 voxels, ~1e-5 voxel).
    float worst = 0.0f;
    for (size_t i = 0; i < a.coverage.size(); ++i) worst = std::max(worst, std::abs(a.coverage[i] - b.coverage[i]));
    EXPECT_LE(worst, 1e-5f);
    EXPECT_NEAR(b.filled_volume() / a.filled_volume(), 1.0, 1e-6);
}

// --- A mesh with holes -----------------------------------------------------------------------------

TEST_F(VolumeTest, SphereWithHolesStillFillsAndDoesNotLeak) {
    const SceneDocument doc = volume_document("sphere", 128, 0.0);
    const mesh::Mesh closed = world_mesh(doc);
    // Cut a few faces out around an axis pole (+y: hit by a whole bundle of y columns) and around a
    // diagonal (where columns along all three axes run through the hole).
    mesh::Mesh holed;
    holed.positions = closed.positions;
    std::vector<glm::uvec3> removed;
    const std::array<glm::dvec3, 2> holes = {glm::dvec3(0, 1, 0), glm::normalize(glm::dvec3(1, 1, 1))};
    for (const auto& t : closed.triangles) {
        const glm::dvec3 centroid = glm::normalize(
            glm::dvec3(closed.positions[t.x]) + glm::dvec3(closed.positions[t.y]) + glm::dvec3(closed.positions[t.z]));
        bool cut = false;
        for (const auto& hole : holes) cut = cut || glm::dot(centroid, hole) > 0.9985;
        (cut ? removed : holed.triangles).push_back(t);
    }
    ASSERT_GE(removed.size(), 6u);
    ASSERT_LE(removed.size(), 60u);

    // mesh::inspect reports the holes: their rims are the edges used once among the removed faces (each
    // edge of the closed sphere had two faces).
    std::map<std::pair<uint32_t, uint32_t>, int> uses;
    for (const auto& t : removed)
        for (int k = 0; k < 3; ++k) ++uses[std::minmax(t[k], t[(k + 1) % 3])];
    const auto rim = static_cast<size_t>(std::count_if(uses.begin(), uses.end(), [](const auto& e) { return e.second == 1; }));
    const mesh::MeshReport report = mesh::inspect(holed);
    EXPECT_FALSE(report.watertight());
    EXPECT_EQ(report.boundary_edges, rim);
    EXPECT_EQ(report.non_manifold_edges, 0u);

    const Volume full = build(doc, closed);
    const Volume v = build(doc, holed);
    ASSERT_EQ(full.grid, v.grid);
    EXPECT_NEAR(v.filled_volume() / full.filled_volume(), 1.0, kVolumeSpec);
    std::cout << "[ info ] holed/closed - 1 = " << v.filled_volume() / full.filled_volume() - 1.0 << " (" << removed.size()
              << " faces removed, " << rim << " rim edges)\n";
    // No leak. A ray that keeps its winding balanced only hits real faces, so nothing outside the closed
    // sphere (centre farther than 1 + half a voxel diagonal) may be covered at all, and in particular no
    // column of covered voxels may run out to the grid's border.
    const double half_diagonal = 0.5 * std::sqrt(3.0) * v.h();
    size_t outside_covered = 0, border_covered = 0, deep_inside = 0, deep_inside_full = 0;
    const auto& d = v.grid.dims;
    v.for_each([&](uint32_t x, uint32_t y, uint32_t z, size_t i) {
        const double r = glm::length(v.centre(x, y, z));
        if (r > 1.0 + half_diagonal && v.coverage[i] != 0.0f) ++outside_covered;
        const bool border = x == 0 || y == 0 || z == 0 || x == d.x - 1 || y == d.y - 1 || z == d.z - 1;
        if (border && v.coverage[i] != 0.0f) ++border_covered;
        // Inside, away from the holes: a voxel entirely within the sphere is full.
        if (r < 0.9 - half_diagonal) {
            ++deep_inside;
            if (v.coverage[i] == 1.0f) ++deep_inside_full;
        }
    });
    EXPECT_EQ(outside_covered, 0u);
    EXPECT_EQ(border_covered, 0u);
    EXPECT_EQ(deep_inside_full, deep_inside);
}

// --- The bunny -------------------------------------------------------------------------------------

TEST_F(VolumeTest, BunnyVoxelizesToItsVolumeAlsoRotatedAndMoved) {
    const mesh::Mesh bunny = mesh::load_obj_file(kBunnyPath);
    ASSERT_TRUE(mesh::inspect(bunny).watertight());
    SceneDocument doc = volume_document("upload:bunny", 128, 0.0);
    struct Pose {
        float scale;
        glm::vec3 rotation_deg, position;
    };
    for (const Pose& pose : {Pose{1.0f, glm::vec3(0.0f), glm::vec3(0.0f)},
                             Pose{0.8f, glm::vec3(30.0f, -50.0f, 20.0f), glm::vec3(0.4f, -0.3f, 0.25f)}}) {
        SCOPED_TRACE(pose.scale);
        const mesh::Mesh world = mesh::transformed(bunny, pose.scale, pose.rotation_deg, pose.position);
        const Volume v = build(doc, world);
        const double mesh_volume = mesh::signed_volume(world);
        // Rotation and translation keep the volume; scale multiplies it by s^3 (float vertices: 1e-5).
        EXPECT_NEAR(mesh_volume / (mesh::signed_volume(bunny) * std::pow(pose.scale, 3.0)), 1.0, 1e-5);
        const double area = surface_area(world);
        const double tolerance = voxel_volume_tolerance(area, mesh_volume, v.h());
        EXPECT_LE(tolerance, kVolumeSpec);
        EXPECT_NEAR(v.filled_volume() / mesh_volume, 1.0, tolerance);
        std::cout << "[ info ] bunny x" << pose.scale << ": filled/mesh - 1 = " << v.filled_volume() / mesh_volume - 1.0
                  << " (tolerance " << tolerance << ")\n";

        // It sits where the transform put it. Coverage can only be positive in voxels that overlap the
        // mesh's bounding box (rays only count inside intervals between real crossings): exact, up to the
        // float rounding of the box in voxel coordinates (1e-3 voxel is ample).
        const mesh::MeshReport report = mesh::inspect(world);
        const glm::vec3 lo = v.grid.to_voxel(report.min), hi = v.grid.to_voxel(report.max);
        size_t stray = 0;
        glm::dvec3 moment(0.0);
        double mass = 0.0;
        v.for_each([&](uint32_t x, uint32_t y, uint32_t z, size_t i) {
            const double c = static_cast<double>(v.coverage[i]);
            if (c == 0.0) return;
            const glm::vec3 p(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
            if (glm::any(glm::lessThanEqual(p + 1.0f, lo - 1e-3f)) || glm::any(glm::greaterThanEqual(p, hi + 1e-3f))) ++stray;
            moment += c * v.centre(x, y, z);
            mass += c;
        });
        EXPECT_EQ(stray, 0u);
        // Centroid: the misassigned volume (at most A h/(2S), see voxel_volume_tolerance) lies on the surface
        // within D of the centroid and moves it by at most 2 D A h/(2S) / V; treating each boundary voxel's
        // coverage as sitting at its centre misplaces at most the boundary shell's volume (sqrt(3) A h:
        // a surface of area A cuts at most sqrt(3) A / h^2 voxels) by half a voxel diagonal.
        const glm::dvec3 expected = volume_centroid(world);
        double reach = 0.0;
        for (const auto& p : world.positions) reach = std::max(reach, glm::length(glm::dvec3(p) - expected));
        const double h = v.h();
        const double centroid_tolerance =
            (reach * area * h / kSubsamples + std::sqrt(3.0) * area * h * 0.5 * std::sqrt(3.0) * h) / mesh_volume;
        std::cout << "[ info ] centroid offset " << glm::length(moment / mass - expected) / h << " voxel (tolerance "
                  << centroid_tolerance / h << ")\n";
        EXPECT_LE(glm::length(moment / mass - expected), centroid_tolerance)
            << "centroid " << moment.x / mass << " " << moment.y / mass << " " << moment.z / mass << " expected "
            << expected.x << " " << expected.y << " " << expected.z << " (h " << h << ")";
    }
}

// --- Index field -----------------------------------------------------------------------------------

TEST_F(VolumeTest, UniformObjectIsIorInsideAndMediumOutside) {
    SceneDocument doc = volume_document("sphere", 64, 0.75);
    doc.object().ior = 1.5;
    doc.medium.ior = 1.33;
    const mesh::Mesh world = world_mesh(doc);
    const Volume v = build(doc, world);
    // A voxel is untouched by the surface when its centre is farther from it than the filter reaches:
    // the spline 1.5 voxels and the lattice smoothing r' = ceil(3 lattice_sigma) voxels along each axis
    // (sqrt(3) times that in space), and the central-difference gradient one voxel further. Inside: use
    // the icosphere's closest face plane.
    double d_min = 1.0;
    for (const auto& t : world.triangles) {
        const glm::dvec3 a(world.positions[t.x]), b(world.positions[t.y]), c(world.positions[t.z]);
        d_min = std::min(d_min, std::abs(glm::dot(glm::normalize(glm::cross(b - a, c - a)), a)));
    }
    const double h = v.h();
    const double lattice_taps = std::ceil(3.0 * static_cast<double>(passes::VoxelizePass::lattice_sigma(0.75f)));
    const double reach = std::sqrt(3.0) * (1.5 + lattice_taps + 1.0) * h;
    size_t inside = 0, outside = 0;
    const float n_object = static_cast<float>(doc.object().ior), n_medium = static_cast<float>(doc.medium.ior);
    v.for_each([&](uint32_t x, uint32_t y, uint32_t z, size_t i) {
        const double r = glm::length(v.centre(x, y, z));
        const glm::vec4 f = v.field[i];
        if (r < d_min - reach) {
            ++inside;
            // Exactly covered (the smoothing of all-ones data sums the same weights it divides by); n is
            // medium + (ior - medium) * 1 in float: 1e-5 is the bound, a few ulps happen.
            EXPECT_NEAR(f.x, n_object, 1e-5f) << x << " " << y << " " << z;
            EXPECT_EQ(glm::vec3(f.y, f.z, f.w), glm::vec3(0.0f)) << x << " " << y << " " << z;
        } else if (r > 1.0 + reach) {
            ++outside;
            EXPECT_EQ(f.x, n_medium) << x << " " << y << " " << z;
            EXPECT_EQ(glm::vec3(f.y, f.z, f.w), glm::vec3(0.0f)) << x << " " << y << " " << z;
        }
    });
    EXPECT_GT(inside, 1000u);
    EXPECT_GT(outside, 1000u);

    // Across the shell the gradient points inward (ior > medium): for every voxel where the gradient is
    // more than float noise, its component along the inward radius is positive.
    float peak = 0.0f;
    for (const auto& f : v.field) peak = std::max(peak, glm::length(glm::vec3(f.y, f.z, f.w)));
    ASSERT_GT(peak, 0.0f);
    size_t shell = 0, outward = 0;
    double cosine_sum = 0.0;
    v.for_each([&](uint32_t x, uint32_t y, uint32_t z, size_t i) {
        const glm::dvec3 g(v.field[i].y, v.field[i].z, v.field[i].w);
        if (glm::length(g) < 0.1 * static_cast<double>(peak)) return;
        ++shell;
        const double cosine = glm::dot(glm::normalize(g), -glm::normalize(v.centre(x, y, z)));
        cosine_sum += cosine;
        if (cosine <= 0.0) ++outward;
    });
    EXPECT_GT(shell, 1000u);
    EXPECT_EQ(outward, 0u);
    std::cout << "[ info ] shell voxels " << shell << ", mean cos(gradient, inward radius) " << cosine_sum / static_cast<double>(shell) << "\n";

    // Its magnitude integrates to ior - medium across the shell: along the x axis line through the
    // centre the central differences telescope to n(inside) - n(outside). Float: ~40 terms of ~1e-7.
    const uint32_t yc = v.grid.dims.y / 2, zc = v.grid.dims.z / 2;
    double integral_in = 0.0, integral_out = 0.0;
    for (uint32_t x = 0; x < v.grid.dims.x; ++x) {
        const double gx = static_cast<double>(v.field[v.at(x, yc, zc)].y);
        // The +x side's inward direction is -x, the -x side's is +x.
        (v.centre(x, yc, zc).x > 0.0 ? integral_out : integral_in) += (v.centre(x, yc, zc).x > 0.0 ? -gx : gx);
    }
    const double jump = static_cast<double>(n_object - n_medium);
    EXPECT_NEAR(integral_in, jump, 1e-5);
    EXPECT_NEAR(integral_out, jump, 1e-5);
}

TEST_F(VolumeTest, FlatInterfaceWidthMatchesSigma) {
    // A cube whose +x face lies exactly on a voxel centre: bounds [-2, 2]^3 at 64^3 give h = 1/16 (exact in
    // binary) and centres at -2 + (i + 1/2)/16; scale 0.96875 = -2 + 47.5/16 puts the faces on the centres
    // of voxels 16 and 47. The y and z columns have 2 of their 4 ray rows inside the face voxel, so the
    // face lies on a row boundary of their rays.
    for (const double sigma : {0.75, 1.5}) {
        SCOPED_TRACE(sigma);
        SceneDocument doc = volume_document("cube", 64, sigma);
        doc.volume.bounds = protocol::Bounds{{-2.0, -2.0, -2.0}, {2.0, 2.0, 2.0}};
        doc.object().scale = 0.96875;
        doc.object().ior = 1.5;
        doc.medium.ior = 1.1;
        const Volume v = build(doc);
        ASSERT_EQ(v.grid.voxel_size, 0.0625f);
        ASSERT_EQ(v.grid.origin, glm::vec3(-2.0f));
        const uint32_t yc = 32, zc = 30;  // 14+ voxels from the cube's edges: the face is flat there
        const uint32_t face = 47;
        const double n_in = 1.5, n_out = 1.1, jump = n_in - n_out;

        // The discrete kernel: the sampled Gaussian of s' = lattice_sigma(sigma) voxels on r = ceil(3 s')
        // taps, normalized; the quadratic B-spline before it reaches 1.5 voxels, so the profile ends within
        // r + 2 of the face.
        const double lattice = static_cast<double>(passes::VoxelizePass::lattice_sigma(static_cast<float>(sigma)));
        const int radius = static_cast<int>(std::ceil(3.0 * lattice));
        const int reach = radius + 2;
        double weight_sum = 0.0, second = 0.0;
        for (int o = -radius; o <= radius; ++o) {
            const double w = std::exp(-0.5 * o * o / (lattice * lattice));
            weight_sum += w;
            second += w * o * o;
        }
        const double kernel_variance = second / weight_sum;

        // (1) Moments of the drop d_i = n_i - n_{i+1} (at i + 1/2). Convolution adds variances: the kernel's,
        // plus the filtered face's. Along x the coverage at a centre is the spline's integral up to the face,
        // so its drops are the spline filtered by a voxel (the cubic B-spline) sampled at half-integers:
        // variance 1/4 + 1/12 = 1/3 exactly (B-splines keep their moments under sampling). The y and z axes
        // see the face through their rows of rays 1/S apart, a sum over rows for the integral: with the face
        // on a row boundary that is the spline sampled 1/S apart, 1/(12 S^2) short of it. The coverage is
        // the mean of the three axes: 1/3 - (2/3) / (12 S^2). The mean is the face. Outside `reach` voxels
        // of the face the coverage is exactly 0 or 1, so the sums are finite and exact up to float rounding
        // (n has ~1e-7 error; 2r+6 terms weighted by (r+3.5)^2 / total drop): 1e-3 voxel^2 bounds it.
        const double face_variance = 1.0 / 3.0 - (2.0 / 3.0) / (12.0 * kSubsamples * kSubsamples);
        double total = 0.0, first = 0.0;
        std::vector<std::pair<double, double>> drops;
        for (int i = static_cast<int>(face) - reach - 2; i <= static_cast<int>(face) + reach + 1; ++i) {
            const double drop = static_cast<double>(v.field[v.at(static_cast<uint32_t>(i), yc, zc)].x) -
                                static_cast<double>(v.field[v.at(static_cast<uint32_t>(i + 1), yc, zc)].x);
            drops.emplace_back(i + 0.5, drop);
            total += drop;
            first += (i + 0.5) * drop;
        }
        const double mean = first / total;
        double variance = 0.0;
        for (const auto& [x, drop] : drops) variance += (x - mean) * (x - mean) * drop;
        variance /= total;
        EXPECT_NEAR(total, jump, 1e-5);
        EXPECT_NEAR(mean, static_cast<double>(face), 1e-4);
        EXPECT_NEAR(variance, kernel_variance + face_variance, 1e-3);

        // (2) The 10%-90% rise distance, by linear interpolation between voxel centres. An ideal step blurred
        // by a Gaussian of s voxels rises 10-90% over 2 x 1.2816 s; here s^2 = kernel variance + 1/4 (the
        // spline's, so s is about sigma). Linear interpolation of samples one voxel
        // apart misreads a value by at most max|n''|/8, which moves a crossing by that over the slope there:
        // for a Gaussian edge max|n''| = jump phi(1)/s^2 and the slope at 10% is jump phi(1.2816)/s, so each
        // end moves at most phi(1) / (8 phi(1.2816) s) and the width twice that.
        const double s = std::sqrt(kernel_variance + 0.25);
        auto phi = [](double x) { return std::exp(-0.5 * x * x) / std::sqrt(2.0 * std::numbers::pi); };
        const double expected_width = 2.0 * 1.2815516 * s;
        const double interpolation = 2.0 * phi(1.0) / (8.0 * phi(1.2815516) * s);
        auto crossing = [&](double level) {  // x (voxel index) where n falls through n_out + level * jump
            const double target = n_out + level * jump;
            for (uint32_t i = face - static_cast<uint32_t>(reach) - 2; i <= face + static_cast<uint32_t>(reach) + 1; ++i) {
                const double a = static_cast<double>(v.field[v.at(i, yc, zc)].x);
                const double b = static_cast<double>(v.field[v.at(i + 1, yc, zc)].x);
                if (a >= target && b < target) return i + (a - target) / (a - b);
            }
            ADD_FAILURE() << "no crossing of level " << level;
            return 0.0;
        };
        const double width = crossing(0.1) - crossing(0.9);
        std::cout << "[ info ] sigma " << sigma << ": drop variance " << variance << " (expected " << kernel_variance + face_variance
                  << "), 10-90 width " << width << " voxels (expected " << expected_width << " +- " << interpolation << ")\n";
        EXPECT_NEAR(width, expected_width, interpolation) << "ideal Gaussian step alone: " << 2.0 * 1.2815516 * sigma;

        // (3) Gradient: along the line it points inward (-x at the +x face) with no y or z part (the face is
        // flat and the line 14 voxels from its edges: the smoothed coverage is the same on neighbouring
        // lines), and dn/dx summed over the shell (per-voxel units, one voxel per sample) is -(ior - medium).
        double integral = 0.0;
        for (uint32_t i = 40; i < 60; ++i) {
            const glm::vec4 f = v.field[v.at(i, yc, zc)];
            EXPECT_LE(f.y, 0.0f) << i;
            EXPECT_NEAR(f.z, 0.0f, 1e-6f) << i;
            EXPECT_NEAR(f.w, 0.0f, 1e-6f) << i;
            integral += static_cast<double>(f.y);
        }
        EXPECT_NEAR(integral, -jump, 1e-5);
    }
}

// --- Analytic lenses -------------------------------------------------------------------------------

// Compares the index field with n(q) and its gradient at every voxel centre; q = (r/R)^2.
template <typename N, typename DnDq>
void expect_lens(const Volume& v, const glm::dvec3& centre, double radius, double n_medium, N n_of_q, DnDq dn_dq) {
    // Evaluated exactly at voxel centres in float: n carries a few ulps (plus the float centre position,
    // ~1e-7 m times |grad n| ~ 1/R), far inside the 1e-3. The gradient per voxel length is
    // dn/dq * 2 d / R^2 * h, also to float precision; 1e-5 covers both.
    const double h = v.h();
    size_t inside = 0, outside = 0, worst_at = 0;
    double worst_n = 0.0, worst_g = 0.0;
    v.for_each([&](uint32_t x, uint32_t y, uint32_t z, size_t i) {
        const glm::dvec3 d = v.centre(x, y, z) - centre;
        const double q = glm::dot(d, d) / (radius * radius);
        const glm::vec4 f = v.field[i];
        if (std::abs(q - 1.0) < 1e-5) return;  // on the rim, float and double may disagree on the side
        double n = n_medium;
        glm::dvec3 g(0.0);
        if (q < 1.0) {
            ++inside;
            n = n_of_q(q);
            g = dn_dq(q) * 2.0 * d / (radius * radius) * h;
        } else {
            ++outside;
        }
        const double en = std::abs(static_cast<double>(f.x) - n);
        const double eg = glm::length(glm::dvec3(f.y, f.z, f.w) - g);
        if (en > worst_n) {
            worst_n = en;
            worst_at = i;
        }
        worst_g = std::max(worst_g, eg);
    });
    EXPECT_GT(inside, 10000u);
    EXPECT_GT(outside, 10000u);
    EXPECT_LE(worst_n, 1e-5) << "at voxel " << worst_at;
    EXPECT_LE(worst_g, 1e-5);
}

TEST_F(VolumeTest, LuneburgAndMaxwellFieldsMatchTheirProfiles) {
    SceneDocument doc = volume_document("sphere", 64, 0.75);
    doc.object().position = {0.2, -0.1, 0.3};
    doc.object().scale = 0.8;
    doc.medium.ior = 1.0;
    const glm::dvec3 centre(0.2, -0.1, 0.3);
    const double radius = 0.8;
    {
        SCOPED_TRACE("luneburg");
        doc.object().index_field = IndexFieldKind::luneburg;
        const Volume v = build(doc);
        expect_lens(v, centre, radius, 1.0, [](double q) { return std::sqrt(2.0 - q); },
                    [](double q) { return -0.5 / std::sqrt(2.0 - q); });
    }
    {
        SCOPED_TRACE("maxwell");
        doc.object().index_field = IndexFieldKind::maxwell;
        doc.object().maxwell_n0 = 2.0;
        const Volume v = build(doc);
        expect_lens(v, centre, radius, 1.0, [](double q) { return 2.0 / (1.0 + q); },
                    [](double q) { return -2.0 / ((1.0 + q) * (1.0 + q)); });
    }
}

// --- Octree ----------------------------------------------------------------------------------------

// The CPU reference, straight from the definition: a level-l node covers voxels [2^l k, 2^l (k+1)) per
// axis; its range is max - min of n over those voxels grown by one on every side (clamped to the grid),
// because level-0 ranges cover each voxel's 3x3x3 neighbourhood. A voxel's level is the largest
// l <= max_level whose node containing it has range < epsilon, 0 if none.
std::vector<uint32_t> reference_levels(const std::vector<float>& n, vk::Extent3 dims, float epsilon, uint32_t max_level) {
    auto at = [&](uint32_t x, uint32_t y, uint32_t z) { return n[(size_t{z} * dims.y + y) * dims.x + x]; };
    std::vector<uint32_t> levels(n.size(), 0);
    for (uint32_t l = 1; l <= max_level; ++l) {
        const uint32_t side = 1u << l;
        for (uint32_t kz = 0; kz * side < dims.z; ++kz)
            for (uint32_t ky = 0; ky * side < dims.y; ++ky)
                for (uint32_t kx = 0; kx * side < dims.x; ++kx) {
                    auto lo_of = [&](uint32_t k) { return k * side == 0 ? 0u : k * side - 1; };
                    auto hi_of = [&](uint32_t k, uint32_t dim) { return std::min((k + 1) * side, dim - 1); };
                    float lo = at(lo_of(kx), lo_of(ky), lo_of(kz)), hi = lo;
                    for (uint32_t z = lo_of(kz); z <= hi_of(kz, dims.z); ++z)
                        for (uint32_t y = lo_of(ky); y <= hi_of(ky, dims.y); ++y)
                            for (uint32_t x = lo_of(kx); x <= hi_of(kx, dims.x); ++x) {
                                lo = std::min(lo, at(x, y, z));
                                hi = std::max(hi, at(x, y, z));
                            }
                    if (!(hi - lo < epsilon)) continue;
                    for (uint32_t z = kz * side; z < std::min((kz + 1) * side, dims.z); ++z)
                        for (uint32_t y = ky * side; y < std::min((ky + 1) * side, dims.y); ++y)
                            for (uint32_t x = kx * side; x < std::min((kx + 1) * side, dims.x); ++x)
                                levels[(size_t{z} * dims.y + y) * dims.x + x] = l;  // ranges grow with l
                }
    }
    return levels;
}

passes::VoxelRange whole(vk::Extent3 dims) { return {glm::uvec3(0u), glm::uvec3(dims.x, dims.y, dims.z)}; }

// passes::OctreePass alone on index fields uploaded into one image; its pyramid and level map stay between
// builds, as a scene's do.
class OctreeRig {
public:
    OctreeRig(vk::Context& context, vk::Extent3 dims)
        : context_(context),
          layout_(passes::octree_layout(dims)),
          field_(context, dims, VK_FORMAT_R32G32B32A32_SFLOAT, "test index field"),
          staging_(context, dims.count() * sizeof(glm::vec4), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::upload,
                   "test index upload"),
          pyramid_(context, layout_.node_count * sizeof(glm::vec2), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                   vk::MemoryUse::readback, "test pyramid"),
          levels_(context, layout_.cell_count * sizeof(uint32_t), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                  vk::MemoryUse::readback, "test levels") {}

    // Uploads `n` and remakes the octree over `region` of it.
    void build(const passes::OctreePass& octree, const std::vector<float>& n, float epsilon, passes::VoxelRange region) {
        std::vector<glm::vec4> texels(n.size());
        for (size_t i = 0; i < n.size(); ++i) texels[i] = glm::vec4(n[i], 0.0f, 0.0f, 0.0f);
        staging_.write(texels.data(), texels.size() * sizeof(glm::vec4));
        vk::run_once(context_, [&](vk::CommandRecorder& r) {
            if (!initialized_) r.init_image(field_);
            r.copy(staging_, field_);
            r.transfer_to_compute_barrier();
            octree.record(r, field_, epsilon, region, pyramid_, levels_);
            r.to_host_barrier();
        });
        initialized_ = true;
    }
    std::vector<glm::vec2> pyramid() const { return read<glm::vec2>(pyramid_, layout_.node_count); }
    std::vector<uint32_t> levels() const { return passes::levels_per_voxel(read<uint32_t>(levels_, layout_.cell_count), field_.extent()); }

private:
    template <typename T>
    static std::vector<T> read(const vk::Buffer& buffer, uint64_t count) {
        std::vector<T> values(count);
        buffer.read(values.data(), count * sizeof(T));
        return values;
    }

    vk::Context& context_;
    passes::OctreeLayout layout_;
    vk::Image3D field_;
    vk::Buffer staging_, pyramid_, levels_;
    bool initialized_ = false;
};

// Runs passes::OctreePass alone on an index field uploaded from `n`.
std::vector<uint32_t> gpu_levels(vk::Context& context, const passes::OctreePass& octree, const std::vector<float>& n,
                                 vk::Extent3 dims, float epsilon) {
    OctreeRig rig(context, dims);
    rig.build(octree, n, epsilon, whole(dims));
    return rig.levels();
}

// A quiet background (noise well below epsilon) with random boxes of random size laid over it: some of
// another index, some noisy, and some offset by about epsilon so that node ranges fall on both sides of
// the threshold. Large empty stretches give coarse leaves, the boxes fine ones.
std::vector<float> random_field(vk::Extent3 dims, float epsilon, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const float background = 1.25f;
    std::vector<float> base(dims.count(), background), noise(dims.count(), 0.3f * epsilon);
    const size_t boxes = std::max<size_t>(3, dims.count() / 20000);
    for (size_t b = 0; b < boxes; ++b) {
        std::array<uint32_t, 3> lo{}, hi{};
        const std::array<uint32_t, 3> d{dims.x, dims.y, dims.z};
        for (size_t a = 0; a < 3; ++a) {
            const auto size = static_cast<uint32_t>(1.0f + unit(rng) * 11.0f);
            lo[a] = static_cast<uint32_t>(unit(rng) * static_cast<float>(d[a] - 1));
            hi[a] = std::min(d[a], lo[a] + size);
        }
        const float kind = unit(rng);
        float value = background, amplitude = 0.3f * epsilon;
        if (kind < 0.3f) value = kind < 0.15f ? 1.0f : 1.5f;                             // another index
        else if (kind < 0.55f) amplitude = 3.0f * epsilon;                              // noisy
        else value = background + epsilon * (0.7f + 0.6f * unit(rng));                  // about epsilon off
        for (uint32_t z = lo[2]; z < hi[2]; ++z)
            for (uint32_t y = lo[1]; y < hi[1]; ++y)
                for (uint32_t x = lo[0]; x < hi[0]; ++x) {
                    const size_t i = (size_t{z} * dims.y + y) * dims.x + x;
                    base[i] = value;
                    noise[i] = amplitude;
                }
    }
    std::vector<float> n(dims.count());
    for (size_t i = 0; i < n.size(); ++i) n[i] = base[i] + noise[i] * (unit(rng) - 0.5f);
    return n;
}

TEST_F(VolumeTest, OctreeLevelsMatchCpuReferenceExactly) {
    const float epsilon = 0.01f;
    // A cube, an odd box (partial nodes at every level), and a grid of more than 65535 x 64 voxels whose
    // per-voxel dispatches fold into a second group dimension (vk::linear_groups).
    for (const vk::Extent3 dims : {vk::Extent3{64, 64, 64}, vk::Extent3{45, 38, 29}, vk::Extent3{160, 160, 168}}) {
        SCOPED_TRACE(std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" + std::to_string(dims.z));
        const passes::OctreeLayout layout = passes::octree_layout(dims);
        // Leaves up to 32 voxels, and a level-l node must fit the grid at least twice along the longest side.
        const uint32_t longest = std::max({dims.x, dims.y, dims.z});
        EXPECT_EQ(layout.max_level, std::min(5u, static_cast<uint32_t>(std::floor(std::log2(longest))) - 1u));
        const std::vector<float> n = random_field(dims, epsilon, 7u + dims.x);
        const std::vector<uint32_t> gpu = gpu_levels(context(), kit().octree, n, dims, epsilon);
        const std::vector<uint32_t> cpu = reference_levels(n, dims, epsilon, layout.max_level);
        ASSERT_EQ(gpu.size(), cpu.size());
        size_t mismatches = 0, first = 0;
        std::array<size_t, 6> histogram{};
        for (size_t i = 0; i < cpu.size(); ++i) {
            if (gpu[i] != cpu[i] && mismatches++ == 0) first = i;
            if (cpu[i] < histogram.size()) ++histogram[cpu[i]];
        }
        EXPECT_EQ(mismatches, 0u) << "first at " << first << ": gpu " << gpu[first] << " cpu " << cpu[first];
        // The field exercises several levels, so the comparison means something.
        size_t used = 0;
        for (size_t c : histogram) used += c > 0 ? 1 : 0;
        std::cout << "[ info ] levels:";
        for (size_t c : histogram) std::cout << " " << c;
        std::cout << "\n";
        EXPECT_GE(used, 4u) << histogram[0] << " " << histogram[1] << " " << histogram[2] << " " << histogram[3]
                            << " " << histogram[4] << " " << histogram[5];
    }
}

// An octree remade over the region where its field changed is the octree of the changed field built
// whole, to the bit: pyramid and level map. Regions of one voxel to 16 per side, at the grid's corners
// and edges, inside one top-level node and across the boundary of two (where the level map of both must
// be remade), on a cube and on an odd box with partial nodes at every level.
TEST_F(VolumeTest, OctreeRemadeOverTheChangedRegionIsTheWholeBuildToTheBit) {
    const float epsilon = 0.01f;
    for (const vk::Extent3 dims : {vk::Extent3{64, 64, 64}, vk::Extent3{45, 38, 29}}) {
        SCOPED_TRACE(std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" + std::to_string(dims.z));
        const glm::uvec3 end(dims.x, dims.y, dims.z);
        const uint32_t top = 1u << passes::octree_layout(dims).max_level;  // a top-level node's side, in voxels
        std::vector<passes::VoxelRange> regions = {
            {glm::uvec3(0u), glm::uvec3(1u)},
            {end - 1u, end},
            {glm::uvec3(top - 1u, 0u, 5u), glm::uvec3(top + 1u, 3u, 6u)},   // across a top-level boundary
            {glm::uvec3(top, 2u, 2u), glm::uvec3(top + 3u, 9u, 4u)},         // from one on, the one below reads it
            {glm::uvec3(3u, 3u, 3u), glm::uvec3(top - 3u, top - 3u, top - 3u)},  // inside one
            {glm::uvec3(0u, 7u, 0u), glm::uvec3(end.x, 8u, end.z)}};
        std::mt19937 rng(dims.x);
        for (int i = 0; i < 6; ++i) {
            passes::VoxelRange random;
            for (int a = 0; a < 3; ++a) {
                random.first[a] = std::uniform_int_distribution<uint32_t>(0, end[a] - 1)(rng);
                random.end[a] = std::min(end[a], random.first[a] + std::uniform_int_distribution<uint32_t>(1, 16)(rng));
            }
            regions.push_back(random);
        }
        const std::vector<float> before = random_field(dims, epsilon, 11u);
        const std::vector<float> elsewhere = random_field(dims, epsilon, 12u);
        OctreeRig resident(context(), dims), fresh(context(), dims);
        resident.build(kit().octree, before, epsilon, whole(dims));
        std::vector<float> n = before;
        for (const passes::VoxelRange& region : regions) {
            auto text = [](glm::uvec3 v) { return std::to_string(v.x) + "," + std::to_string(v.y) + "," + std::to_string(v.z); };
            SCOPED_TRACE("region " + text(region.first) + " .. " + text(region.end));
            // Inside the region, another field: other boxes, other noise.
            for (uint32_t z = region.first.z; z < region.end.z; ++z)
                for (uint32_t y = region.first.y; y < region.end.y; ++y)
                    for (uint32_t x = region.first.x; x < region.end.x; ++x) {
                        const size_t v = (size_t{z} * dims.y + y) * dims.x + x;
                        n[v] = elsewhere[v];
                    }
            resident.build(kit().octree, n, epsilon, region);
            fresh.build(kit().octree, n, epsilon, whole(dims));
            EXPECT_TRUE(resident.pyramid() == fresh.pyramid());
            EXPECT_TRUE(resident.levels() == fresh.levels());
        }
        // The changes reached the level map, so the comparison means something.
        EXPECT_NE(fresh.levels(), gpu_levels(context(), kit().octree, before, dims, epsilon));
    }
}

TEST_F(VolumeTest, OctreeIsCoarseInHomogeneousRegionsAndFineInTheShell) {
    // Unit sphere, default margin 0.35 m: h = 2.7 m / 64, radius R = 23.7 voxels, centre at voxel
    // coordinate 32 (the corner shared by voxels 31 and 32).
    SceneDocument doc = volume_document("sphere", 64, 0.75);
    const Volume v = build(doc, true);
    const auto& d = v.grid.dims;
    ASSERT_EQ(d, (vk::Extent3{64, 64, 64}));
    const float epsilon = static_cast<float>(doc.volume.octree_epsilon);
    std::vector<float> n(v.field.size());
    for (size_t i = 0; i < n.size(); ++i) n[i] = v.field[i].x;
    // Exactly the CPU reference on a real field too.
    EXPECT_EQ(v.levels, reference_levels(n, d, epsilon, passes::octree_layout(d).max_level));

    // Deep inside, n is exactly ior wherever every voxel within the smoothing's reach (sqrt(3) ceil(3 sigma)
    // = 5.2 voxels) lies wholly inside (centre within R - sqrt(3)/2): within 23.7 - 0.9 - 5.2 = 17.6 voxels
    // of the centre. The level-3 node [32, 40)^3 grown by one is [31, 40]^3, whose voxel centres lie within
    // sqrt(3) x 8.5 = 14.7 voxels of the centre: uniform, so voxel (32, 32, 32) is at least level 3.
    const double h = v.h();
    const double radius = 1.0 / h;
    ASSERT_LT(std::sqrt(3.0) * 8.5, radius - 0.5 * std::sqrt(3.0) - std::sqrt(3.0) * 3.0);
    EXPECT_GE(v.levels[v.at(32, 32, 32)], 3u);
    EXPECT_GE(v.levels[v.at(39, 35, 33)], 3u);
    // The empty margin: the corner node [0, 8)^3 grown to [0, 8]^3 has centres at least 23.5 voxels from the
    // centre per axis (40.7 in space), beyond R + 0.9 + 5.2 = 29.8 where coverage is exactly 0.
    ASSERT_GT(std::sqrt(3.0) * 23.5, radius + 0.5 * std::sqrt(3.0) + std::sqrt(3.0) * 3.0);
    EXPECT_GE(v.levels[v.at(0, 0, 0)], 3u);
    EXPECT_GE(v.levels[v.at(d.x - 1, d.y - 1, d.z - 1)], 3u);

    // The smoothed shell is level 0: a voxel whose gradient component |g_a| >= epsilon / 2 sees neighbours
    // along a differing by 2|g_a| >= epsilon inside its own 3x3x3 range, so even its level-1 node fails.
    // (+1e-6: n's float rounding.)
    size_t steep = 0, not_leaf0 = 0;
    for (size_t i = 0; i < v.field.size(); ++i) {
        const glm::vec4 f = v.field[i];
        if (std::max({std::abs(f.y), std::abs(f.z), std::abs(f.w)}) < 0.5f * epsilon + 1e-6f) continue;
        ++steep;
        if (v.levels[i] != 0) ++not_leaf0;
    }
    EXPECT_GT(steep, 1000u);
    EXPECT_EQ(not_leaf0, 0u);
}


// --- Several objects ---------------------------------------------------------------------------------

// Scenes of several objects on a fixed lattice (volume.bounds), so that moving one does not move it.
SceneDocument objects_document(const nlohmann::json& objects) {
    return protocol::parse_scene({{"objects", objects},
                                  {"volume", {{"resolution", 96}, {"bounds", {{"min", {-1.5, -1, -1}}, {"max", {1.5, 1, 1}}}}}},
                                  {"medium", {{"ior", 1.0}}}});
}

// Where two objects overlap, the voxel takes the field of the one with more coverage, and where both
// cover it fully, of the denser; the order of their names does not matter.
TEST_F(VolumeTest, OverlappingObjectsTakeTheFieldOfTheOneMoreInsideAndInsideBothOfTheDenser) {
    auto two = [](const char* light_name, const char* dense_name) {
        return objects_document({{light_name, {{"position", {-0.3, 0, 0}}, {"scale", 0.5}, {"ior", 1.3}}},
                                 {dense_name, {{"position", {0.3, 0, 0}}, {"scale", 0.5}, {"ior", 1.7}}}});
    };
    for (const auto& [light_name, dense_name] : {std::pair{"a", "b"}, std::pair{"b", "a"}}) {
        SCOPED_TRACE(std::string("lighter glass named ") + light_name);
        const SceneDocument doc = two(light_name, dense_name);
        scene::SceneGpu gpu(kit());
        scene::RunOptions options;
        options.limit = scene::kVoxelize | scene::kIndexField;
        const scene::RunStats stats = gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
        EXPECT_EQ(stats.voxelized.size(), 2u);
        const auto field = gpu.read_index_field();
        const auto numbers = gpu.read_object_numbers();  // 1 + the object's place in name order
        const uint32_t light_number = std::string(light_name) < dense_name ? 1u : 2u;
        const passes::GridGeometry& g = gpu.grid();
        auto voxel_at = [&](glm::vec3 p) {
            const glm::uvec3 v(g.to_voxel(p));
            return (size_t{v.z} * g.dims.y + v.y) * g.dims.x + v.x;
        };
        // Inside the lighter sphere only (0.5 from the other's centre is its surface; 0.75 is clear of it).
        const size_t light_only = voxel_at({-0.45f, 0.0f, 0.0f});
        EXPECT_NEAR(field[light_only].x, 1.3f, 1e-5f);
        EXPECT_EQ(numbers[light_only], light_number);
        // Inside both: the denser.
        const size_t both = voxel_at({0.0f, 0.0f, 0.0f});
        EXPECT_NEAR(field[both].x, 1.7f, 1e-5f);
        EXPECT_EQ(numbers[both], 3u - light_number);
        // Far from both: the medium, and no object.
        const size_t clear = voxel_at({0.0f, 0.9f, 0.9f});
        EXPECT_EQ(field[clear], glm::vec4(1.0f, 0.0f, 0.0f, 0.0f));
        EXPECT_EQ(numbers[clear], 0u);
    }
}

// Moving one object of three voxelizes that object only and remakes the index field over its boxes
// (before and after) only, and the volume it leaves is the one a fresh build of the moved scene makes,
// to the bit; so does an index edit of one object, and removing one. Both where the lattice holds the
// field and where a field atlas does: there the move gives the cube a cluster of its own anew, and the
// clusters that stay are carried over from the old atlas.
TEST_F(VolumeTest, MovingOneObjectVoxelizesItAloneAndGivesTheVolumeOfAFreshBuild) {
    const nlohmann::json objects = {{"ball", {{"position", {-1.0, 0, 0}}, {"scale", 0.35}}},
                                    {"cube", {{"mesh", "cube"}, {"position", {0.0, 0, 0}}, {"scale", 0.3}, {"ior", 1.33}}},
                                    {"lens", {{"index_field", "luneburg"}, {"position", {1.0, 0, 0}}, {"scale", 0.35}}}};
    // A box their boxes fill, and one twice as wide at the same voxel, of which they hold under half.
    SceneDocument crowded = objects_document(objects);
    crowded.volume.bounds = protocol::Bounds{{-1.5, -0.6, -0.6}, {1.5, 0.6, 0.6}};
    SceneDocument wide = crowded;
    wide.volume.bounds = protocol::Bounds{{-3, -1.2, -1.2}, {3, 1.2, 1.2}};
    wide.volume.resolution = 2 * crowded.volume.resolution;
    for (const SceneDocument* doc : {&crowded, &wide}) {
        const bool atlas = doc == &wide;
        SCOPED_TRACE(atlas ? "field atlas" : "lattice");
        const SceneDocument& before = *doc;
        const SceneDocument after = protocol::apply_merge_patch(
            before, {{"objects", {{"cube", {{"position", {0.1, 0.2, -0.1}}, {"rotation_deg", {0, 30, 0}}}}}}});
        scene::RunOptions options;
        options.limit = scene::kVoxelize | scene::kIndexField | scene::kOctree;
        scene::SceneGpu resident(kit());
        EXPECT_EQ(resident.run(scene::kAllPasses, before, worlds(before), nullptr, options).voxelized,
                  (std::vector<std::string>{"ball", "cube", "lens"}));
        const scene::FieldAtlas layout = resident.field_atlas();
        EXPECT_EQ(layout.dense, !atlas);
        const scene::PassSet stale = scene::passes_invalidated(before, after);
        EXPECT_TRUE(stale & scene::kVoxelize);
        EXPECT_EQ(resident.run(stale, after, worlds(after), nullptr, options).voxelized, std::vector<std::string>{"cube"});
        if (atlas) {
            EXPECT_FALSE(resident.field_atlas() == layout);
        }
        expect_volume_of_a_fresh_build(resident, after, options);
        // An index edit of one object remakes the field over its box only, to the same bits.
        const SceneDocument denser = protocol::apply_merge_patch(after, {{"objects", {{"cube", {{"ior", 1.9}}}}}});
        EXPECT_TRUE(resident.run(scene::passes_invalidated(after, denser), denser, worlds(denser), nullptr, options)
                        .voxelized.empty());
        expect_volume_of_a_fresh_build(resident, denser, options);
        // Removing an object voxelizes nothing (the others keep their coverage), and the field then is
        // that of the two left.
        const SceneDocument removed = protocol::apply_merge_patch(denser, {{"objects", {{"ball", nullptr}}}});
        EXPECT_TRUE(resident.run(scene::passes_invalidated(denser, removed), removed, worlds(removed), nullptr, options)
                        .voxelized.empty());
        expect_volume_of_a_fresh_build(resident, removed, options);
    }
}

// The octree is remade over what the moved object's boxes reach, and its level map under the top-level
// nodes they meet: a ball that leaves one top-level node for the boundary of two others leaves the node
// it left all medium, a leaf of the top level to its far corner, as in a fresh build of the moved scene.
TEST_F(VolumeTest, MovingAnObjectAcrossTopLevelNodesGivesTheOctreeOfAFreshBuild) {
    const nlohmann::json objects = {{"ball", {{"position", {-1.0, 0.5, 0.5}}, {"scale", 0.15}}},
                                    {"cube", {{"mesh", "cube"}, {"position", {1.0, -0.5, -0.5}}, {"scale", 0.2}, {"ior", 1.33}}}};
    const SceneDocument before = objects_document(objects);
    const SceneDocument after = protocol::apply_merge_patch(before, {{"objects", {{"ball", {{"position", {0.5, 0.5, 0.5}}}}}}});
    scene::RunOptions options;
    options.limit = scene::kVoxelize | scene::kIndexField | scene::kOctree;
    scene::SceneGpu resident(kit());
    resident.run(scene::kAllPasses, before, worlds(before), nullptr, options);
    const passes::GridGeometry& g = resident.grid();
    const uint32_t max_level = passes::octree_layout(g.dims).max_level;
    ASSERT_EQ(max_level, 5u);
    const uint32_t top = 1u << max_level;
    // The ball's box before lies in the top-level node from (0, 32, 32) and after crosses from the node
    // from (32, 32, 32) into the one from (64, 32, 32); the cube's lies below them all.
    const double sigma = before.volume.smoothing;
    const passes::ObjectBox was = scene::object_boxes(g, worlds(before), sigma).at("ball");
    const passes::ObjectBox is = scene::object_boxes(g, worlds(after), sigma).at("ball");
    const passes::ObjectBox cube = scene::object_boxes(g, worlds(after), sigma).at("cube");
    auto top_node = [&](glm::uvec3 voxel) { return voxel / top; };
    const glm::uvec3 was_last = was.offset + glm::uvec3(was.box.dims.x, was.box.dims.y, was.box.dims.z) - 1u;
    const glm::uvec3 is_last = is.offset + glm::uvec3(is.box.dims.x, is.box.dims.y, is.box.dims.z) - 1u;
    ASSERT_EQ(top_node(was.offset), glm::uvec3(0u, 1u, 1u));
    ASSERT_EQ(top_node(was_last), glm::uvec3(0u, 1u, 1u));
    ASSERT_EQ(top_node(is.offset), glm::uvec3(1u, 1u, 1u));
    ASSERT_EQ(top_node(is_last), glm::uvec3(2u, 1u, 1u));
    ASSERT_LT(cube.offset.y + cube.box.dims.y, top - 1u);  // below what the nodes at y 32 read
    // A voxel of the node the ball leaves whose level-1 node reads none of the ball's box (voxels z 61..64).
    const glm::uvec3 corner(1u, top + 1u, 2u * top - 1u);
    ASSERT_LT(was_last.z, corner.z - 2u);
    const size_t corner_index = (size_t{corner.z} * g.dims.y + corner.y) * g.dims.x + corner.x;
    EXPECT_LT(resident.read_levels()[corner_index], max_level);

    resident.run(scene::passes_invalidated(before, after), after, worlds(after), nullptr, options);
    EXPECT_EQ(resident.read_levels()[corner_index], max_level);
    expect_volume_of_a_fresh_build(resident, after, options);
}


// --- Field atlas (several objects) ------------------------------------------------------------------

using AtlasBox = std::pair<glm::uvec3, glm::uvec3>;

// The layout of several boxes: whole map cells, no cell in two clusters, every box in one, slots that
// keep the octree's nodes of up to a cell whole and do not overlap; the map finds each lattice voxel of
// a cluster where its slot holds it, and around the rest the largest aligned cube that holds no cluster.
TEST(FieldAtlas, ClustersHoldEveryBoxAndTheMapFindsEachVoxelAndTheMediumAroundThem) {
    passes::GridGeometry lattice;
    lattice.voxel_size = 0.01f;
    lattice.dims = {150, 37, 130};  // not whole cells: clusters at the far faces are clipped
    const uint32_t max_level = passes::octree_layout(lattice.dims).max_level;
    // Two boxes that overlap (one cluster), one that touches neither, one cut by the lattice's far face,
    // and an empty one.
    const std::vector<AtlasBox> boxes = {{{10, 3, 10}, {30, 20, 35}}, {{27, 5, 30}, {45, 30, 50}},
                                         {{90, 0, 70}, {101, 13, 89}}, {{130, 20, 120}, {150, 37, 130}},
                                         {{60, 10, 60}, {60, 20, 70}}};
    const scene::FieldAtlas atlas = scene::sparse_field_atlas(lattice, boxes, max_level, 4096);
    ASSERT_FALSE(atlas.dense);
    ASSERT_EQ(atlas.clusters.size(), 3u);
    const glm::uvec3 dims(lattice.dims.x, lattice.dims.y, lattice.dims.z);
    for (const AtlasBox& b : boxes) {
        if (glm::any(glm::greaterThanEqual(b.first, b.second))) continue;
        const auto holder = std::find_if(atlas.clusters.begin(), atlas.clusters.end(), [&](const auto& c) {
            return glm::all(glm::lessThanEqual(c.first, b.first)) && glm::all(glm::greaterThanEqual(c.end, b.second));
        });
        EXPECT_NE(holder, atlas.clusters.end());
    }
    auto slot_end = [](const scene::FieldAtlas::Cluster& c) {
        return c.atlas_first + (c.extent() + FIELD_CELL - 1u) / FIELD_CELL * FIELD_CELL;
    };
    for (size_t i = 0; i < atlas.clusters.size(); ++i) {
        const auto& c = atlas.clusters[i];
        EXPECT_EQ(c.first % FIELD_CELL, glm::uvec3(0u));
        EXPECT_EQ(c.atlas_first % FIELD_CELL, glm::uvec3(0u));
        EXPECT_TRUE(glm::all(glm::equal(c.end, dims) || glm::equal(c.end % FIELD_CELL, glm::uvec3(0u))));
        EXPECT_TRUE(glm::all(glm::lessThanEqual(slot_end(c), glm::uvec3(atlas.dims.x, atlas.dims.y, atlas.dims.z))));
        for (size_t j = i + 1; j < atlas.clusters.size(); ++j) {
            const auto& o = atlas.clusters[j];
            EXPECT_FALSE(glm::all(glm::lessThan(c.first, o.end)) && glm::all(glm::lessThan(o.first, c.end)));
            EXPECT_FALSE(glm::all(glm::lessThan(c.atlas_first, slot_end(o))) && glm::all(glm::lessThan(o.atlas_first, slot_end(c))));
        }
    }
    for (uint32_t z = 0; z < dims.z; ++z)
        for (uint32_t y = 0; y < dims.y; ++y)
            for (uint32_t x = 0; x < dims.x; ++x) {
                const glm::uvec3 v(x, y, z);
                const auto in = std::find_if(atlas.clusters.begin(), atlas.clusters.end(), [&](const auto& c) { return c.contains(v); });
                const std::optional<glm::uvec3> stored = atlas.atlas_voxel(v);
                ASSERT_EQ(stored.has_value(), in != atlas.clusters.end()) << x << " " << y << " " << z;
                if (stored) {
                    ASSERT_EQ(*stored, v - in->first + in->atlas_first);
                }
            }
    // Around the clusters, the map's level L: the aligned cube of 2^L voxels around the cell holds no
    // cluster, and (below the top level) the one of 2^(L+1) does.
    auto cube_is_clear = [&](glm::uvec3 cell, uint32_t level) {
        const glm::uvec3 first = (cell * FIELD_CELL) >> level << level, end = first + (1u << level);
        return std::none_of(atlas.clusters.begin(), atlas.clusters.end(), [&](const auto& c) {
            return glm::all(glm::lessThan(c.first, end)) && glm::all(glm::lessThan(first, c.end));
        });
    };
    uint32_t empty_cells = 0;
    for (uint32_t z = 0; z < atlas.cells.z; ++z)
        for (uint32_t y = 0; y < atlas.cells.y; ++y)
            for (uint32_t x = 0; x < atlas.cells.x; ++x) {
                const uint32_t entry = atlas.map_entry({x, y, z});
                if (!(entry & FIELD_EMPTY)) continue;
                ++empty_cells;
                const uint32_t level = entry - FIELD_EMPTY;
                ASSERT_GE(level, FIELD_CELL_LEVEL);
                ASSERT_LE(level, max_level);
                ASSERT_TRUE(cube_is_clear({x, y, z}, level));
                if (level < max_level) {
                    ASSERT_FALSE(cube_is_clear({x, y, z}, level + 1));
                }
            }
    EXPECT_GT(empty_cells, 0u);
    // The same boxes in another order give the same layout.
    std::vector<AtlasBox> reversed(boxes.rbegin(), boxes.rend());
    EXPECT_TRUE(scene::sparse_field_atlas(lattice, reversed, max_level, 4096) == atlas);
    // Clusters that do not fit the device's image sides are refused, not clipped; the renderer reports
    // that as a scene it cannot render.
    EXPECT_THROW(scene::sparse_field_atlas(lattice, boxes, max_level, 32), std::length_error);
    std::map<std::string, passes::ObjectBox> object_boxes;
    for (size_t i = 0; i < boxes.size(); ++i) {
        const glm::uvec3 size = glm::max(boxes[i].second, boxes[i].first) - boxes[i].first;
        object_boxes[std::to_string(i)] = {{lattice.origin, lattice.voxel_size, {size.x, size.y, size.z}}, boxes[i].first};
    }
    EXPECT_FALSE(scene::field_atlas_for(lattice, object_boxes, false, 4096).dense);
    EXPECT_THROW(scene::field_atlas_for(lattice, object_boxes, false, 32), scene::RenderError);
}

// An object's resolution sets the lattice's voxel: the scene's divided by the smallest whole factor
// that gives the object at least that many voxels along its own longest side, whatever its rotation;
// at most passes::kMaxLightFactor; the finest object decides.
TEST(FieldAtlas, ObjectResolutionDividesTheScenesVoxelByAWholeFactor) {
    auto grid_of = [](const nlohmann::json& objects) {
        const SceneDocument doc = protocol::parse_scene(
            {{"objects", objects}, {"volume", {{"resolution", 64}, {"bounds", {{"min", {-8, -1, -8}}, {"max", {8, 1, 8}}}}}}});
        return scene::grid_for(doc, scene::world_meshes(doc, nullptr));
    };
    const passes::GridGeometry plain = grid_of({{"a", {{"scale", 0.5}}}});
    EXPECT_EQ(plain.light_factor, 1u);
    EXPECT_FLOAT_EQ(plain.voxel_size, 0.25f);
    // A sphere of diameter 1 at 16 voxels: 1/16 m asked of a 1/4 m scene voxel -> factor 4.
    const passes::GridGeometry fine = grid_of({{"a", {{"scale", 0.5}, {"resolution", 16}}}, {"b", {{"scale", 0.3}}}});
    EXPECT_EQ(fine.light_factor, 4u);
    EXPECT_FLOAT_EQ(fine.voxel_size, 0.0625f);
    EXPECT_EQ(fine.dims, (vk::Extent3{256, 32, 256}));
    EXPECT_EQ(fine.coarsened(fine.light_factor), plain.dims);
    // 17 voxels: 4 no longer suffices.
    EXPECT_EQ(grid_of({{"a", {{"scale", 0.5}, {"resolution", 17}}}}).light_factor, 5u);
    // A cube turned 45 degrees is as long along its own sides as unturned.
    EXPECT_EQ(grid_of({{"a", {{"mesh", "cube"}, {"scale", 0.5}, {"resolution", 16}, {"rotation_deg", {0, 45, 30}}}}}).light_factor, 4u);
    EXPECT_EQ(grid_of({{"a", {{"scale", 0.5}, {"resolution", 512}}}}).light_factor, passes::kMaxLightFactor);
}

// A scene of several objects stores its field in an atlas; the lookups see there, voxel for voxel,
// the field a dense lattice holds: an object next to a far one has the index field and coverage it has
// alone on the same lattice, to the float rounding of its voxelization, and its frame is the frame it
// makes alone but for the few photons whose steps round differently.
TEST_F(VolumeTest, AnObjectInAFieldAtlasHasTheFieldAndFrameItHasInADenseLattice) {
    const nlohmann::json ball = {{"position", {-0.6, 0, 0}}, {"scale", 0.45}, {"ior", 1.5},
                                 {"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}};
    // The far object: a small cube in the lattice's corner, behind the camera's view and the light's cone.
    const nlohmann::json far = {{"mesh", "cube"}, {"position", {1.3, -0.8, -0.8}}, {"scale", 0.1}};
    auto document = [&](const nlohmann::json& objects) {
        return protocol::parse_scene(
            {{"objects", objects},
             {"volume", {{"resolution", 96}, {"bounds", {{"min", {-1.5, -1, -1}}, {"max", {1.5, 1, 1}}}}}},
             {"medium", {{"ior", 1.0}, {"extinction", {0.3, 0.3, 0.3}}, {"scattering", {0.3, 0.3, 0.3}}}},
             {"lights", {{"spot", {{"type", "spot"}, {"position", {-0.6, 0.95, 0}}, {"direction", {0, -1, 0}}, {"cone_deg", 30}}}}},
             {"camera", {{"position", {-0.6, 0, 3}}, {"target", {-0.6, 0, 0}}, {"fov_deg", 40}}},
             {"floor", {{"enabled", false}}},
             {"image", {{"width", 64}, {"height", 64}}},
             {"photons", {{"count", 65536}}}});
    };
    const SceneDocument alone = document({{"ball", ball}});
    const SceneDocument pair = document({{"ball", ball}, {"far", far}});
    scene::SceneGpu dense(kit()), sparse(kit());
    dense.run(scene::kAllPasses, alone, worlds(alone), nullptr);
    sparse.run(scene::kAllPasses, pair, worlds(pair), nullptr);
    ASSERT_TRUE(dense.field_atlas().dense);
    ASSERT_FALSE(sparse.field_atlas().dense);
    ASSERT_EQ(sparse.field_atlas().clusters.size(), 2u);
    const passes::GridGeometry& g = dense.grid();
    ASSERT_TRUE(g == sparse.grid());
    EXPECT_LT(sparse.field_atlas().dims.count(), g.dims.count() / 2);
    // Voxel for voxel outside the far cube's box.
    const passes::ObjectBox far_box = scene::object_boxes(g, worlds(pair), pair.volume.smoothing).at("far");
    const auto dense_field = dense.read_index_field(), sparse_field = sparse.read_index_field();
    const auto dense_coverage = dense.read_coverage(), sparse_coverage = sparse.read_coverage();
    size_t compared = 0;
    float field_error = 0.0f, coverage_error = 0.0f;
    for (uint32_t z = 0; z < g.dims.z; ++z)
        for (uint32_t y = 0; y < g.dims.y; ++y)
            for (uint32_t x = 0; x < g.dims.x; ++x) {
                const glm::uvec3 v(x, y, z), first = far_box.offset;
                const glm::uvec3 end = first + glm::uvec3(far_box.box.dims.x, far_box.box.dims.y, far_box.box.dims.z);
                if (glm::all(glm::greaterThanEqual(v, first)) && glm::all(glm::lessThan(v, end))) continue;
                const size_t i = (size_t{z} * g.dims.y + y) * g.dims.x + x;
                for (int c = 0; c < 4; ++c) field_error = std::max(field_error, std::abs(dense_field[i][c] - sparse_field[i][c]));
                coverage_error = std::max(coverage_error, std::abs(dense_coverage[i] - sparse_coverage[i]));
                ++compared;
            }
    EXPECT_GT(compared, g.dims.count() * 9 / 10);
    // Alone, the ball is voxelized over the whole lattice, here over its own box: the same sums of
    // coverage from positions relative to another corner, a few float roundings (2^-23 relative) of
    // values of at most 1, and n and grad n are linear in them with weights below 1.
    std::printf("[ info ] atlas against dense: field %.3e, coverage %.3e\n", double{field_error}, double{coverage_error});
    EXPECT_LT(field_error, 1e-6f);
    EXPECT_LT(coverage_error, 1e-6f);
    // The frames: the same photons through the same field, but a trilinear fetch at an atlas position
    // rounds its weights differently from one at the lattice's, the voxelizer's sums over another box
    // round differently (the 2e-7 above), and the octree's leaves stop at a map cell: a photon's path
    // may part in the last bits and one of its deposits' stochastic roundings fall the other way. If a
    // fraction q of the photons drew anew, the frames would differ by sqrt(q) times what two seeds'
    // frames differ by (photon noise adds in quadrature): under half of that says fewer than a quarter
    // of the photons part. A field seen wrongly (the ball a voxel off, the medium where glass is) moves
    // the caustic and the ball's pixels by far more than the noise.
    SceneDocument reseeded = alone;
    reseeded.photons.seed = alone.photons.seed + 1;
    scene::SceneGpu other(kit());
    other.run(scene::kAllPasses, reseeded, worlds(reseeded), nullptr);
    auto difference = [](const std::vector<glm::vec4>& a, const std::vector<glm::vec4>& b) {
        double d = 0.0;
        for (size_t i = 0; i < a.size(); ++i) d += glm::length(glm::dvec3(a[i]) - glm::dvec3(b[i]));
        return d;
    };
    const auto frame = dense.read_hdr();
    const double atlas_difference = difference(frame, sparse.read_hdr());
    const double seed_difference = difference(frame, other.read_hdr());
    std::printf("[ info ] atlas against dense: frames differ by %.3e, two seeds by %.3e\n", atlas_difference, seed_difference);
    EXPECT_GT(seed_difference, 0.0);
    EXPECT_LT(atlas_difference, 0.5 * seed_difference);
}

// The memory estimate the renderer budgets with covers what a scene holds once built, one object or
// several (their field atlas rather than the lattice), and does not overstate it by more than the transient
// buffers and the conservative per-voxel sums it adds (2x); and it covers what an interactive light edit
// after the still holds.
TEST_F(VolumeTest, MemoryEstimateCoversWhatASceneHolds) {
    const SceneDocument one = protocol::parse_scene({{"image", {{"width", 64}, {"height", 64}}}, {"volume", {{"resolution", 64}}}});
    const SceneDocument three = objects_document({{"ball", {{"position", {-1.0, 0, 0}}, {"scale", 0.35}}},
                                                  {"cube", {{"mesh", "cube"}, {"scale", 0.3}}},
                                                  {"lens", {{"index_field", "luneburg"}, {"position", {1.0, 0, 0}}, {"scale", 0.35}}}});
    // Objects far apart asking for voxels four times finer than the scene's: a field atlas on a lattice
    // of light_factor 4, the radiance grid at the scene's voxel.
    const SceneDocument sparse = protocol::parse_scene(
        {{"image", {{"width", 64}, {"height", 64}}},
         {"objects", {{"ball", {{"position", {-1.5, 0, 0}}, {"scale", 0.3}, {"resolution", 22}}},
                      {"cube", {{"mesh", "cube"}, {"position", {1.5, 0, 1}}, {"scale", 0.25}, {"resolution", 20}}}}},
         {"volume", {{"resolution", 40}, {"bounds", {{"min", {-2, -1, -2}}, {"max", {2, 1, 2}}}}}}});
    for (const SceneDocument* doc : {&one, &three, &sparse}) {
        SCOPED_TRACE(doc->objects.size());
        const int64_t before = context().allocated_bytes();
        scene::SceneGpu gpu(kit());
        scene::RunOptions still;
        still.still_ends = true;  // as the renderer's still frames keep them
        gpu.run(scene::kAllPasses, *doc, worlds(*doc), nullptr, still);
        const int64_t held = context().allocated_bytes() - before;
        if (doc == &sparse) {
            EXPECT_EQ(gpu.grid().light_factor, 4u);
            EXPECT_LT(gpu.field_atlas().dims.count(), gpu.grid().dims.count() / 10);
        }
        uint64_t object_voxels = 0;
        for (const auto& [name, box] : scene::object_boxes(gpu.grid(), worlds(*doc), doc->volume.smoothing))
            object_voxels += box.box.dims.count();
        const int64_t estimate = scene::estimate_scene_bytes(gpu.grid(), gpu.field_atlas().dims.count(), object_voxels,
                                                             gpu.grid().coarsened(gpu.grid().light_factor).count(),
                                                             doc->image.width, doc->image.height);
        std::printf("[ info ] %zu object(s): holds %.1f MiB, estimate %.1f MiB\n", doc->objects.size(),
                    static_cast<double>(held) / (1 << 20), static_cast<double>(estimate) / (1 << 20));
        EXPECT_GE(estimate, held);
        EXPECT_LE(estimate, 2 * held);
        // An interactive light edit after it: a coarser radiance grid, and the adaptive density's images.
        scene::RunOptions interactive;
        interactive.radiance_factor = 3;
        interactive.adaptive_density = true;
        gpu.run(scene::kPhotons | scene::kView, *doc, worlds(*doc), nullptr, interactive);
        EXPECT_GE(estimate, context().allocated_bytes() - before) << "after an interactive light edit";
    }
}

}  // namespace
}  // namespace refract
