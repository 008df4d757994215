// Triangle meshes: the built-in shapes and uploaded OBJ files, validated and inspected the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

namespace refract::mesh {

struct Mesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::uvec3> triangles;  // indices into positions, counter-clockwise seen from outside
};

// The axis-aligned box around a mesh's positions; an empty mesh's is empty (min above max).
struct Bounds {
    glm::vec3 min{1e30f}, max{-1e30f};
};
Bounds bounds(const Mesh& mesh);

// A mesh that cannot be used; the message says why in words a user can act on.
class MeshError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

struct MeshLimits {
    size_t max_bytes = 64u << 20;      // OBJ text
    size_t max_triangles = 2'000'000;  // after triangulation
    // 'v' lines, counted before each is kept: vertices no face uses cost memory too. Three a triangle is
    // the most a mesh of max_triangles separate triangles needs.
    size_t max_vertices = 6'000'000;
    // Polygons: a convex face is fanned in O(n) whatever its size; any other face is ear-clipped in O(n^2),
    // so its corners are limited, and so is the sum over such faces of corners^2 (the triangulation work).
    size_t max_concave_polygon_corners = 4096;
    uint64_t max_concave_polygon_work = 32ull << 20;  // two faces of 4096 corners
    float max_abs_coordinate = 1e6f;
};

// Topology facts a user should know about an upload (a hole leaks nothing, but they should hear of it).
struct MeshReport {
    size_t vertices = 0;
    size_t triangles = 0;
    size_t boundary_edges = 0;      // edges used by exactly one triangle
    size_t non_manifold_edges = 0;  // edges used by three or more triangles
    size_t degenerate_triangles = 0;
    bool watertight() const { return boundary_edges == 0 && non_manifold_edges == 0; }
    glm::vec3 min{0.0f}, max{0.0f};  // axis-aligned bounds
};

// Built-ins, centred at the origin: sphere of radius 1, cube from -1 to 1, torus of radii 1 and 0.35 in
// the XZ plane, and an equilateral prism (60 degree apex, the dispersing prism of optics benches) whose
// cross-section in the XY plane has circumradius 1 with its apex towards +y, from z = -1 to 1. Closed
// and consistently oriented.
Mesh make_sphere(uint32_t subdivisions = 5);
Mesh make_cube();
Mesh make_prism();
Mesh make_torus(uint32_t major_segments = 96, uint32_t minor_segments = 48);
// A closed, watertight "Stanford-bunny-like" test shape (body, haunches, head, two ears, tail, paws):
// an implicit surface of a few ellipsoidal metaballs polygonized by marching tetrahedra, fitted so its
// largest half-extent is 1, centred at the origin, coordinates rounded to 5 decimals: 28,496 triangles.
// Deterministic: examples/meshes/bunny.obj is to_obj() of this mesh (tests/mesh_test.cpp checks it and
// rewrites the file when REFRACT_WRITE_EXAMPLES=1).
Mesh make_blobby_bunny();

// Writes the mesh as OBJ text ("v x y z" with `decimals` decimals, then "f a b c" with 1-based indices),
// preceded by `comment` as '#' lines when it is not empty. `decimals` < 0: each coordinate as the shortest
// text that reads back as the same float (an upload made from a mesh in memory keeps it exactly).
std::string to_obj(const Mesh& mesh, std::string_view comment = {}, int decimals = 5);

// Parses OBJ text (polygons are triangulated, see triangulate.h). Throws MeshError on empty/unparseable
// input, no faces, NaN or absurd coordinates, out-of-range indices, or limits exceeded (a non-convex
// polygon over max_concave_polygon_corners included). All objects/groups are merged into
// one mesh; triangles are kept as given; vertices no face refers to (normals, texture coordinates, points
// and lines are ignored) are dropped.
Mesh parse_obj(std::string_view obj_text, const MeshLimits& limits = {});
// Reads and parses an OBJ file. Throws MeshError (unreadable file included).
Mesh load_obj_file(const std::string& path, const MeshLimits& limits = {});

// Vertices are welded by exact position before edges are counted, so split vertices do not count as holes.
// Degenerate: a repeated (welded) index, or an area that is zero to float precision.
MeshReport inspect(const Mesh& mesh);

// The rotation of XYZ Euler angles (degrees): X first, then Y, then Z.
glm::dmat3 rotation(glm::dvec3 rotation_deg);

// Applies scale, then rotation (degrees, X then Y then Z), then translation. A negative scale mirrors the
// mesh, so the triangles are flipped to stay outward-facing.
Mesh transformed(const Mesh& mesh, float scale, glm::vec3 rotation_deg, glm::vec3 translation);

// Signed volume by the divergence theorem (positive for outward-facing triangles).
double signed_volume(const Mesh& mesh);

}  // namespace refract::mesh
