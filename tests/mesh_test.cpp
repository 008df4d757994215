// Triangle meshes: built-in shapes, OBJ parsing and its rejections, inspection, transforms, the example
// bunny.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "mesh/mesh.h"
#include "mesh/triangulate.h"

namespace refract::mesh {
namespace {

namespace fs = std::filesystem;

const std::string kAssimpModels = "/usr/share/assimp/models";
const std::string kBunnyPath = std::string(REFRACT_SOURCE_DIR) + "/examples/meshes/bunny.obj";

// Every undirected edge (after welding equal positions) is walked once in each direction: a closed,
// consistently oriented surface.
bool consistently_oriented(const Mesh& mesh) {
    std::map<std::tuple<float, float, float>, uint32_t> ids;
    std::vector<uint32_t> canonical;
    for (const auto& p : mesh.positions) {
        canonical.push_back(
            ids.try_emplace({p.x, p.y, p.z}, static_cast<uint32_t>(ids.size())).first->second);
    }
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    for (const auto& t : mesh.triangles) {
        const uint32_t v[3] = {canonical[t.x], canonical[t.y], canonical[t.z]};
        for (int k = 0; k < 3; ++k) ++directed[{v[k], v[(k + 1) % 3]}];
    }
    for (const auto& [edge, count] : directed) {
        if (count != 1) return false;
        const auto reverse = directed.find({edge.second, edge.first});
        if (reverse == directed.end() || reverse->second != 1) return false;
    }
    return true;
}

// The MeshError message of `fn`, or a failure when it does not throw one.
template <typename Fn>
std::string error_of(Fn&& fn) {
    try {
        fn();
    } catch (const MeshError& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "threw a non-MeshError: " << e.what();
        return {};
    }
    ADD_FAILURE() << "did not throw";
    return {};
}

// ---------------------------------------------------------------------------------------------------------
// Built-ins

TEST(Builtins, SphereVolumeAndSize) {
    const Mesh sphere = make_sphere(5);
    EXPECT_EQ(sphere.triangles.size(), 20480u);
    const double exact = 4.0 / 3.0 * std::numbers::pi;
    EXPECT_NEAR(signed_volume(sphere), exact, 0.005 * exact);
    for (const auto& p : sphere.positions) ASSERT_NEAR(glm::length(p), 1.0f, 1e-6f);
    EXPECT_EQ(make_sphere(0).triangles.size(), 20u);
    EXPECT_EQ(make_sphere(2).triangles.size(), 320u);
}

TEST(Builtins, CubeVolumeIsExactlyEight) {
    const Mesh cube = make_cube();
    EXPECT_EQ(signed_volume(cube), 8.0);
    const MeshReport r = inspect(cube);
    EXPECT_EQ(r.min, glm::vec3(-1.0f));
    EXPECT_EQ(r.max, glm::vec3(1.0f));
}

TEST(Builtins, TorusVolumeAndPlacement) {
    const Mesh torus = make_torus();
    const double exact = 2.0 * std::numbers::pi * std::numbers::pi * 1.0 * 0.35 * 0.35;
    EXPECT_NEAR(signed_volume(torus), exact, 0.01 * exact);
    const MeshReport r = inspect(torus);  // in the XZ plane, axis Y
    EXPECT_NEAR(r.max.x, 1.35f, 1e-5f);
    EXPECT_NEAR(r.max.z, 1.35f, 1e-3f);
    EXPECT_NEAR(r.max.y, 0.35f, 1e-3f);
    EXPECT_NEAR(r.min.y, -0.35f, 1e-3f);
}

TEST(Builtins, AreWatertightAndConsistentlyOriented) {
    for (const auto& [name, mesh] : {std::pair{"sphere", make_sphere(3)}, std::pair{"cube", make_cube()},
                                     std::pair{"torus", make_torus()}, std::pair{"prism", make_prism()}}) {
        SCOPED_TRACE(name);
        const MeshReport r = inspect(mesh);
        EXPECT_EQ(r.boundary_edges, 0u);
        EXPECT_EQ(r.non_manifold_edges, 0u);
        EXPECT_EQ(r.degenerate_triangles, 0u);
        EXPECT_TRUE(r.watertight());
        EXPECT_EQ(r.triangles, mesh.triangles.size());
        EXPECT_TRUE(consistently_oriented(mesh));
        EXPECT_GT(signed_volume(mesh), 0.0);
    }
}

TEST(Builtins, RejectAbsurdParameters) {
    EXPECT_NE(error_of([] { make_sphere(20); }).find("subdivisions"), std::string::npos);
    EXPECT_NE(error_of([] { make_torus(2, 10); }).find("segments"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------------------
// Inspection

TEST(Inspect, SphereWithFacesRemovedReportsItsHoles) {
    const Mesh sphere = make_sphere(2);
    // One face gone: a triangular hole of 3 edges.
    Mesh one = sphere;
    one.triangles.erase(one.triangles.begin());
    EXPECT_EQ(inspect(one).boundary_edges, 3u);
    EXPECT_FALSE(inspect(one).watertight());

    // Face 0 and a neighbour sharing an edge: a 4-edge hole.
    const glm::uvec3 first = sphere.triangles[0];
    size_t neighbour = 0;
    for (size_t i = 1; i < sphere.triangles.size() && neighbour == 0; ++i) {
        int shared = 0;
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b) shared += sphere.triangles[i][a] == first[b] ? 1 : 0;
        }
        if (shared == 2) neighbour = i;
    }
    ASSERT_NE(neighbour, 0u);
    Mesh two = sphere;
    two.triangles.erase(two.triangles.begin() + static_cast<std::ptrdiff_t>(neighbour));
    two.triangles.erase(two.triangles.begin());
    EXPECT_EQ(inspect(two).boundary_edges, 4u);

    // Five faces far apart (every 60th): 15 boundary edges.
    Mesh five;
    five.positions = sphere.positions;
    for (size_t i = 0; i < sphere.triangles.size(); ++i) {
        if (i % 60 != 7 || i > 300) five.triangles.push_back(sphere.triangles[i]);
    }
    ASSERT_EQ(five.triangles.size(), sphere.triangles.size() - 5);
    EXPECT_EQ(inspect(five).boundary_edges, 15u);
    EXPECT_EQ(inspect(five).non_manifold_edges, 0u);
}

TEST(Inspect, WeldsSplitVerticesBeforeCountingEdges) {
    const Mesh cube = make_cube();
    Mesh split;  // every triangle with its own three vertices, as OBJ files with several shapes often are
    for (const auto& t : cube.triangles) {
        const auto base = static_cast<uint32_t>(split.positions.size());
        for (int k = 0; k < 3; ++k) split.positions.push_back(cube.positions[t[k]]);
        split.triangles.emplace_back(base, base + 1, base + 2);
    }
    const MeshReport r = inspect(split);
    EXPECT_EQ(r.vertices, 36u);
    EXPECT_EQ(r.triangles, 12u);
    EXPECT_EQ(r.boundary_edges, 0u);
    EXPECT_TRUE(r.watertight());
}

TEST(Inspect, CountsDegenerateAndNonManifold) {
    Mesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {2, 0, 0}, {3, 0, 0}};
    m.triangles = {{0, 1, 2},
                   {1, 0, 3},
                   {0, 1, 4},   // edge 0-1 used three times
                   {2, 2, 4},   // repeated index
                   {1, 5, 6}};  // collinear: zero area
    const MeshReport r = inspect(m);
    EXPECT_EQ(r.non_manifold_edges, 1u);
    EXPECT_EQ(r.degenerate_triangles, 2u);
    EXPECT_FALSE(r.watertight());
    EXPECT_EQ(r.min, glm::vec3(0, -1, 0));
    EXPECT_EQ(r.max, glm::vec3(3, 1, 1));
}

// ---------------------------------------------------------------------------------------------------------
// Transforms

TEST(Transform, ScaleThenRotateXYZThenTranslate) {
    Mesh m;
    m.positions = {{0, 1, 0}};
    // X by 90 takes +Y to +Z; then Y by 90 takes +Z to +X. (Y first would leave +Y alone, then X gives +Z.)
    const Mesh r = transformed(m, 2.0f, {90, 90, 0}, {10, 20, 30});
    EXPECT_NEAR(r.positions[0].x, 12.0f, 1e-5f);
    EXPECT_NEAR(r.positions[0].y, 20.0f, 1e-5f);
    EXPECT_NEAR(r.positions[0].z, 30.0f, 1e-5f);
    // Z by 90 takes +X to +Y.
    Mesh x;
    x.positions = {{1, 0, 0}};
    const Mesh rz = transformed(x, 1.0f, {0, 0, 90}, {0, 0, 0});
    EXPECT_NEAR(rz.positions[0].x, 0.0f, 1e-6f);
    EXPECT_NEAR(rz.positions[0].y, 1.0f, 1e-6f);
}

TEST(Transform, VolumeScalesAndOrientationSurvivesMirroring) {
    const Mesh cube = make_cube();
    EXPECT_NEAR(signed_volume(transformed(cube, 0.5f, {30, 45, 60}, {3, -2, 1})), 1.0, 1e-5);
    const Mesh mirrored = transformed(cube, -2.0f, {0, 0, 0}, {0, 0, 0});
    EXPECT_NEAR(signed_volume(mirrored), 64.0, 1e-9);
    EXPECT_TRUE(consistently_oriented(mirrored));
}

// ---------------------------------------------------------------------------------------------------------
// OBJ parsing

TEST(Obj, ParsesAndTriangulatesPolygons) {
    const Mesh m = parse_obj(
        "# a unit square and a pentagon\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vn 0 0 1\nvt 0 0\n"
        "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
        "o second\n"
        "v 0 0 2\nv 1 0 2\nv 2 1 2\nv 1 2 2\nv 0 1 2\n"
        "f -5 -4 -3 -2 -1\n");
    EXPECT_EQ(m.triangles.size(), 2u + 3u);
    EXPECT_EQ(m.positions.size(), 9u);
    for (const auto& t : m.triangles) {
        for (int k = 0; k < 3; ++k) EXPECT_LT(t[k], m.positions.size());
    }
}

TEST(Obj, MergesShapesAndDropsUnreferencedVertices) {
    const Mesh m = parse_obj(
        "v 9 9 9\n"  // referenced by nothing
        "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n"
        "g b\nv 0 0 1\nf 2 3 5\n"
        "l 1 2\np 1\n");
    EXPECT_EQ(m.triangles.size(), 2u);
    EXPECT_EQ(m.positions.size(), 4u);
    EXPECT_EQ(inspect(m).max, glm::vec3(1.0f));
}

TEST(Obj, AcceptsLineEndingsBomAndUtf8Comments) {
    for (const std::string& text :
         {std::string("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n"),
          std::string("v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3"),
          std::string("\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
          std::string("# caf\xC3\xA9 \xE2\x80\x94 mod\xC3\xA8le\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
          std::string("v +1e-1 2.E0 -3.5e+0 1.0\nv 1 0 0\nv 0 1 0 # comment\nf 1 2 3\n")}) {
        const Mesh m = parse_obj(text);
        EXPECT_EQ(m.triangles.size(), 1u);
    }
    const Mesh numbers = parse_obj("v +1e-1 2.E0 -3.5e+0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    EXPECT_NEAR(numbers.positions[0].x, 0.1f, 1e-7f);
    EXPECT_NEAR(numbers.positions[0].y, 2.0f, 1e-7f);
    EXPECT_NEAR(numbers.positions[0].z, -3.5f, 1e-7f);
}

TEST(Obj, RoundTripsThroughToObj) {
    const Mesh sphere = make_sphere(2);
    const std::string text = to_obj(sphere, "a sphere\nsecond line");
    EXPECT_EQ(text.rfind("# a sphere\n# second line\nv ", 0), 0u);
    const Mesh back = parse_obj(text);
    ASSERT_EQ(back.triangles, sphere.triangles);
    ASSERT_EQ(back.positions.size(), sphere.positions.size());
    for (size_t i = 0; i < back.positions.size(); ++i) {
        EXPECT_NEAR(glm::distance(back.positions[i], sphere.positions[i]), 0.0f, 1e-5f);
    }
    EXPECT_EQ(to_obj(Mesh{{{-0.000001f, 0.5f, -1.0f}}, {}}), "v 0.00000 0.50000 -1.00000\n");
}

TEST(Obj, RejectsEmptyAndFacelessInput) {
    EXPECT_NE(error_of([] { parse_obj(""); }).find("empty"), std::string::npos);
    EXPECT_NE(error_of([] { parse_obj("  \n\r\n\t\n"); }).find("empty"), std::string::npos);
    EXPECT_NE(error_of([] { parse_obj("# only a comment\nusemtl x\n"); }).find("no vertices"),
              std::string::npos);
    EXPECT_NE(error_of([] { parse_obj("v 0 0 0\nv 1 0 0\nl 1 2\n"); }).find("no faces"), std::string::npos);
    EXPECT_NE(error_of([] { parse_obj("v 0 0 0\nv 1 0 0\nf 1 2\n"); }).find("at least 3"), std::string::npos);
    EXPECT_NE(
        error_of([] { parse_obj("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"); }).find("fewer than 3 coordinates"),
        std::string::npos);
}

TEST(Obj, RejectsNonFiniteAndAbsurdCoordinates) {
    const auto message = [](const std::string& first_vertex) {
        return error_of([&] { parse_obj(first_vertex + "\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"); });
    };
    EXPECT_NE(message("v nan 0 0").find("NaN"), std::string::npos);
    EXPECT_NE(message("v 0 -NaN 0").find("NaN"), std::string::npos);
    EXPECT_NE(message("v 0 0 inf").find("infinite"), std::string::npos);
    EXPECT_NE(message("v 1e400 0 0").find("out of range"), std::string::npos);
    EXPECT_NE(message("v 2e6 0 0").find("too large"), std::string::npos);
    EXPECT_NE(message("v abc 0 0").find("not a number"), std::string::npos);
    EXPECT_NE(message("v nan 0 0").find("line 1"), std::string::npos);
    MeshLimits tight;
    tight.max_abs_coordinate = 10.0f;
    EXPECT_NE(error_of([&] { parse_obj("v 0 0 0\nv 11 0 0\nv 0 1 0\nf 1 2 3\n", tight); }).find("too large"),
              std::string::npos);
}

TEST(Obj, RejectsBadIndices) {
    const std::string verts = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
    EXPECT_NE(error_of([&] { parse_obj(verts + "f 1 2 5\n"); }).find("out of range"), std::string::npos);
    EXPECT_NE(error_of([&] { parse_obj(verts + "f 1 2 3 9\n"); }).find("out of range"), std::string::npos);
    EXPECT_NE(error_of([&] { parse_obj(verts + "f -1 -2 -5\n"); }).find("out of range"), std::string::npos);
    EXPECT_NE(error_of([&] { parse_obj(verts + "f 0 1 2\n"); }).find("index 0"), std::string::npos);
    EXPECT_NE(error_of([&] { parse_obj(verts + "f 1 x 2\n"); }).find("invalid vertex index"),
              std::string::npos);
    EXPECT_NE(
        error_of([&] { parse_obj(verts + "f 1 2 3 # no comments here\n"); }).find("invalid vertex index"),
        std::string::npos);
    EXPECT_NE(error_of([&] { parse_obj(verts + "f 1 2 3\nf 1 2 99999999999999999999\n"); }).find("line 6"),
              std::string::npos);
    // A face may only use vertices defined before it.
    EXPECT_NE(error_of([] { parse_obj("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n"); }).find("out of range"),
              std::string::npos);
}

TEST(Obj, RejectsNonTextInput) {
    std::string utf16le = "\xFF\xFE";
    for (const char c : std::string("v 0 0 0\n")) {
        utf16le += c;
        utf16le += '\0';
    }
    EXPECT_NE(error_of([&] { parse_obj(utf16le); }).find("OBJ must be ASCII/UTF-8 text"), std::string::npos);
    std::string no_bom = utf16le.substr(2);
    EXPECT_NE(error_of([&] { parse_obj(no_bom); }).find("OBJ must be ASCII/UTF-8 text"), std::string::npos);
    std::string binary;
    for (int i = 0; i < 4096; ++i) binary += static_cast<char>(1 + (i * 37) % 255);
    EXPECT_NE(error_of([&] { parse_obj(binary); }).find("OBJ must be ASCII/UTF-8 text"), std::string::npos);
}

TEST(Obj, EnforcesLimits) {
    const std::string box = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 4 3 2 1\n";
    MeshLimits limits;
    limits.max_bytes = box.size() - 1;
    const std::string too_big = error_of([&] { parse_obj(box, limits); });
    EXPECT_NE(too_big.find("over the limit"), std::string::npos) << too_big;
    EXPECT_NE(too_big.find("bytes"), std::string::npos) << too_big;
    limits.max_bytes = box.size();
    EXPECT_EQ(parse_obj(box, limits).triangles.size(), 4u);

    limits.max_triangles = 3;
    const std::string too_many = error_of([&] { parse_obj(box, limits); });
    EXPECT_NE(too_many.find("triangles"), std::string::npos) << too_many;
    EXPECT_NE(too_many.find("limit"), std::string::npos) << too_many;
    limits.max_triangles = 4;
    EXPECT_EQ(parse_obj(box, limits).triangles.size(), 4u);
}

// ---------------------------------------------------------------------------------------------------------
// Large polygons (issue 20): convex faces of any size are fanned in linear time; non-convex ones are
// ear-clipped up to MeshLimits::max_concave_polygon_corners and refused beyond it, before any cutting.

// One face of n corners in the plane z = 0.5, tilted so it is not axis-aligned: a circle (convex), or a
// star whose corners alternate between radius 1 and `inner`.
std::string polygon_obj(size_t n, double inner = 1.0) {
    std::string text;
    text.reserve(n * 40);
    char buf[96];
    for (size_t i = 0; i < n; ++i) {
        const double a = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n);
        const double r = (i % 2 == 1) ? inner : 1.0;
        const double x = r * std::cos(a), y = r * std::sin(a);
        std::snprintf(buf, sizeof buf, "v %.9f %.9f %.9f\n", x, 0.6 * y, 0.5 + 0.8 * y);
        text += buf;
    }
    text += 'f';
    for (size_t i = 1; i <= n; ++i) {
        text += ' ';
        text += std::to_string(i);
    }
    text += '\n';
    return text;
}

// The shoelace area of the same polygon in its own plane, and the area of a triangle soup measured along
// the polygon's normal (a triangle facing the wrong way subtracts, one outside the polygon adds).
double star_area(size_t n, double inner) {
    double twice = 0.0;
    for (size_t i = 0; i < n; ++i) {
        const double a0 = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n);
        const double a1 = 2.0 * std::numbers::pi * static_cast<double>(i + 1) / static_cast<double>(n);
        const double r0 = (i % 2 == 1) ? inner : 1.0, r1 = ((i + 1) % 2 == 1) ? inner : 1.0;
        twice += r0 * r1 * std::sin(a1 - a0);
    }
    return 0.5 * twice;  // the tilt (y scaled by 0.6, z by 0.8) is a rotation, so the area is the same
}

struct Coverage {
    double signed_area = 0.0;    // along the face normal
    double absolute_area = 0.0;  // every triangle counted positive
};

Coverage coverage(const Mesh& m) {
    const glm::dvec3 normal(0.0, -0.8, 0.6);  // of the plane spanned by x and (0, 0.6, 0.8)
    Coverage c;
    for (const auto& t : m.triangles) {
        const glm::dvec3 a(m.positions[t.x]), b(m.positions[t.y]), d(m.positions[t.z]);
        const glm::dvec3 cross = glm::cross(b - a, d - a);
        c.signed_area += 0.5 * glm::dot(cross, normal);
        c.absolute_area += 0.5 * glm::length(cross);
    }
    return c;
}

void expect_exact_cover(const Mesh& m, size_t n, double inner) {
    ASSERT_EQ(m.triangles.size(), n - 2);
    EXPECT_EQ(m.positions.size(), n);
    const double area = star_area(n, inner);
    const Coverage c = coverage(m);
    // Equal signed and absolute sums: no triangle is flipped, so none overlaps another or leaves the face.
    EXPECT_NEAR(c.signed_area, area, 1e-5 * area);
    EXPECT_NEAR(c.absolute_area, area, 1e-5 * area);
}

TEST(Polygons, SmallConcaveFacesAreEarClippedInsideTheirBoundary) {
    // An L-shaped hexagon and a concave quad ("dart"): a fan from the first corner would leave the face.
    const Mesh l_shape = parse_obj("v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 4 5 6 1 2 3\n");
    ASSERT_EQ(l_shape.triangles.size(), 4u);
    double area = 0.0;
    for (const auto& t : l_shape.triangles) {
        const glm::dvec3 a(l_shape.positions[t.x]), b(l_shape.positions[t.y]), c(l_shape.positions[t.z]);
        const double z = glm::cross(b - a, c - a).z;
        EXPECT_GT(z, 0.0);
        area += 0.5 * z;
    }
    EXPECT_DOUBLE_EQ(area, 3.0);
    const Mesh dart = parse_obj("v 0 0 0\nv 1 0.2 0\nv 2 0 0\nv 1 2 0\nf 2 3 4 1\n");
    ASSERT_EQ(dart.triangles.size(), 2u);
    for (const auto& t : dart.triangles) {
        const glm::dvec3 a(dart.positions[t.x]), b(dart.positions[t.y]), c(dart.positions[t.z]);
        EXPECT_GT(glm::cross(b - a, c - a).z, 0.0);
    }
}

TEST(Polygons, ConvexFaceOf80000CornersIsFanned) {
    const size_t n = 80'000;
    expect_exact_cover(parse_obj(polygon_obj(n)), n, 1.0);
}

TEST(Polygons, StarShapedFacesUpToTheLimitAreEarClipped) {
    for (const size_t n : {size_t{10}, size_t{1000}, MeshLimits{}.max_concave_polygon_corners}) {
        SCOPED_TRACE(n);
        expect_exact_cover(parse_obj(polygon_obj(n, 0.5)), n, 0.5);
    }
    // Ear clipping itself on a convex face agrees with the fan.
    const Mesh circle = parse_obj(polygon_obj(16));
    std::vector<uint32_t> corners(16);
    for (uint32_t i = 0; i < 16; ++i) corners[i] = i;
    Mesh clipped{circle.positions, {}};
    ear_clip_polygon(project_polygon(clipped.positions, corners), corners, clipped.triangles);
    expect_exact_cover(clipped, 16, 1.0);
}

TEST(Polygons, LargeNonConvexFacesAreRefusedNamingTheLimit) {
    const std::string star = error_of([] { parse_obj(polygon_obj(80'000, 0.5)); });
    EXPECT_NE(star.find("non-convex polygon with 80000 corners"), std::string::npos) << star;
    EXPECT_NE(star.find("limit of 4096"), std::string::npos) << star;
    EXPECT_NE(star.find("line 80001"), std::string::npos) << star;

    // The largest face the triangle limit lets through, max_triangles + 2 corners, zigzagging over three
    // vertices (so not convex): refused after the O(n) convexity test. One corner more is refused by the
    // pre-scan's triangle count.
    const size_t most = MeshLimits{}.max_triangles + 2;
    std::string worst = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf";
    for (size_t i = 0; i < most; ++i) {
        worst += ' ';
        worst += "1232"[i % 4];
    }
    const std::string message = error_of([&] { parse_obj(worst + "\n"); });
    EXPECT_NE(message.find("non-convex polygon with " + std::to_string(most) + " corners"), std::string::npos)
        << message;
    const std::string over = error_of([&] { parse_obj(worst + " 1\n"); });
    EXPECT_NE(over.find("more than the limit of 2000000 triangles"), std::string::npos) << over;

    // Many faces each under the corner limit still add up to the work limit.
    std::string many;
    for (int k = 0; k < 5; ++k) many += polygon_obj(1000, 0.5);
    MeshLimits limits;
    limits.max_concave_polygon_work = 3 * 1000 * 1000;
    const std::string total = error_of([&] { parse_obj(many, limits); });
    EXPECT_NE(total.find("sum of corners^2"), std::string::npos) << total;
    EXPECT_NE(total.find("limit of 3000000"), std::string::npos) << total;
}

TEST(ObjFile, MissingFileNamesThePath) {
    const std::string path = "/nonexistent/dir/model.obj";
    const std::string message = error_of([&] { load_obj_file(path); });
    EXPECT_NE(message.find(path), std::string::npos) << message;
    const std::string dir_message = error_of([] { load_obj_file("/tmp"); });
    EXPECT_NE(dir_message.find("/tmp"), std::string::npos) << dir_message;
}

TEST(ObjFile, FileOverMaxBytesIsRejectedBeforeReading) {
    MeshLimits limits;
    limits.max_bytes = 100;
    const std::string message = error_of([&] { load_obj_file(kBunnyPath, limits); });
    EXPECT_NE(message.find("over the limit"), std::string::npos) << message;
    EXPECT_NE(message.find(kBunnyPath), std::string::npos) << message;
}

// ---------------------------------------------------------------------------------------------------------
// The assimp test models (Debian package assimp-testmodels)

TEST(AssimpModels, InvalidObjFilesAreRejectedWithAReason) {
    const fs::path dir = kAssimpModels + "/invalid";
    if (!fs::is_directory(dir)) GTEST_SKIP() << "assimp-testmodels is not installed";
    // What each known file is wrong with, in words the message must contain.
    const std::map<std::string, std::string> reason = {
        {"empty.obj", "empty"},            // zero bytes
        {"malformed.obj", "index"},        // out-of-range and zero vertex indices
        {"malformed2.obj", "at least 3"},  // an 'f' line without vertices
    };
    int checked = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        if (entry.path().extension() != ".obj") continue;
        const std::string name = entry.path().filename().string();
        SCOPED_TRACE(name);
        const std::string message = error_of([&] { load_obj_file(entry.path().string()); });
        EXPECT_NE(message.find(entry.path().string()), std::string::npos) << message;
        const auto expected = reason.find(name);
        if (expected != reason.end()) {
            EXPECT_NE(message.find(expected->second), std::string::npos) << message;
        } else {
            EXPECT_GT(message.size(), entry.path().string().size() + 10) << message;
        }
        ++checked;
    }
    EXPECT_GE(checked, 3);
}

TEST(AssimpModels, Utf16AndPointCloudAreRejected) {
    if (!fs::is_directory(kAssimpModels + "/OBJ")) GTEST_SKIP() << "assimp-testmodels is not installed";
    const std::string utf16 = error_of([] { load_obj_file(kAssimpModels + "/OBJ/box_UTF16BE.obj"); });
    EXPECT_NE(utf16.find("OBJ must be ASCII/UTF-8 text"), std::string::npos) << utf16;
    const std::string cloud = error_of([] { load_obj_file(kAssimpModels + "/OBJ/point_cloud.obj"); });
    EXPECT_NE(cloud.find("no faces"), std::string::npos) << cloud;
}

TEST(AssimpModels, BoxAndSpiderLoad) {
    if (!fs::is_directory(kAssimpModels + "/OBJ")) GTEST_SKIP() << "assimp-testmodels is not installed";
    const Mesh box = load_obj_file(kAssimpModels + "/OBJ/box.obj");
    EXPECT_EQ(box.triangles.size(), 12u);
    EXPECT_EQ(box.positions.size(), 8u);
    const MeshReport r = inspect(box);
    EXPECT_TRUE(r.watertight());
    EXPECT_EQ(r.min, glm::vec3(-0.5f));
    EXPECT_EQ(r.max, glm::vec3(0.5f));
    EXPECT_NEAR(std::fabs(signed_volume(box)), 1.0, 1e-6);

    const Mesh spider = load_obj_file(kAssimpModels + "/OBJ/spider.obj");
    EXPECT_GE(spider.triangles.size(), 1368u);  // 1368 'f' lines, some of them quads
    const MeshReport s = inspect(spider);
    EXPECT_GT(s.vertices, 0u);
    EXPECT_LT(s.min.x, s.max.x);
}

// ---------------------------------------------------------------------------------------------------------
// The example bunny

TEST(Bunny, CommittedFileIsReproducibleWatertightAndBigEnough) {
    const Mesh generated = make_blobby_bunny();
    if (std::getenv("REFRACT_WRITE_EXAMPLES") != nullptr) {
        fs::create_directories(fs::path(kBunnyPath).parent_path());
        std::ofstream(kBunnyPath, std::ios::binary)
            << to_obj(generated,
                      "Blobby \"Stanford-bunny-like\" test mesh: closed, watertight, consistently oriented.\n"
                      "Generated by refract::mesh::make_blobby_bunny() (server/mesh/mesh.cpp);\n"
                      "regenerate with REFRACT_WRITE_EXAMPLES=1 mesh_test --gtest_filter='Bunny.*'");
    }

    const Mesh bunny = load_obj_file(kBunnyPath);
    EXPECT_LE(fs::file_size(kBunnyPath), 1'500'000u);
    const MeshReport r = inspect(bunny);
    EXPECT_GE(r.triangles, 5000u);
    EXPECT_EQ(r.boundary_edges, 0u);
    EXPECT_EQ(r.non_manifold_edges, 0u);
    EXPECT_EQ(r.degenerate_triangles, 0u);
    EXPECT_TRUE(r.watertight());
    EXPECT_EQ(r.vertices, bunny.positions.size());
    EXPECT_TRUE(consistently_oriented(bunny));
    EXPECT_GT(signed_volume(bunny), 0.3);
    for (int a = 0; a < 3; ++a) {
        EXPECT_GE(r.min[a], -1.0f);
        EXPECT_LE(r.max[a], 1.0f);
        EXPECT_NEAR(r.min[a] + r.max[a], 0.0f, 1e-4f);  // centred
    }
    EXPECT_NEAR(std::max({r.max.x, r.max.y, r.max.z}), 1.0f, 1e-4f);

    // The file is exactly what the generator makes (up to decimal round-off).
    ASSERT_EQ(bunny.triangles, generated.triangles);
    ASSERT_EQ(bunny.positions.size(), generated.positions.size());
    float worst = 0.0f;
    for (size_t i = 0; i < bunny.positions.size(); ++i) {
        worst = std::max(worst, glm::distance(bunny.positions[i], generated.positions[i]));
    }
    EXPECT_LT(worst, 1e-5f);
}

}  // namespace
TEST(ObjLimits, VerticesAreCountedBeforeTheyAreKept) {
    // Vertices no face uses cost memory all the same: 64 MiB of "v 0 0 0" lines are 8 M of them.
    MeshLimits limits;
    limits.max_vertices = 4;
    const std::string tetrahedron = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    EXPECT_EQ(parse_obj(tetrahedron, limits).positions.size(), 4u);
    const std::string message = error_of([&] { parse_obj("v 5 5 5\n" + tetrahedron, limits); });
    EXPECT_NE(message.find("more than the limit of 4 vertices (on line 5)"), std::string::npos) << message;
    EXPECT_EQ(MeshLimits{}.max_vertices, 3 * MeshLimits{}.max_triangles);
}

}  // namespace refract::mesh
