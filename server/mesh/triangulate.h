// Triangulation of one polygon face of an OBJ file, in time linear in its corners when it is convex and
// quadratic (bounded by the caller) when it is not.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace refract::mesh {

// What triangulate_polygon() found out about a face before it cut it.
enum class PolygonShape {
    convex,     // fanned from its first corner: O(n)
    concave,    // cut by ear clipping: O(n^2)
};

// Convex when, projected onto the plane its Newell normal is most aligned with, every turn goes the
// same way (or straight on) and the boundary winds once. O(n); `positions` indexed by `corners`.
bool is_convex_polygon(std::span<const glm::vec3> positions, std::span<const uint32_t> corners);

// Appends n - 2 triangles (indices taken from `corners`, in the face's winding) that cover the polygon.
// A convex face is fanned; any other face is ear-clipped in O(n^2) time. A self-intersecting or
// degenerate face still gets n - 2 triangles (where no ear exists a convex corner, else any corner, is
// cut off), which may overlap. Returns which way it was cut.
PolygonShape triangulate_polygon(std::span<const glm::vec3> positions, std::span<const uint32_t> corners,
                                 std::vector<glm::uvec3>& out);

// Ear clipping only (the convex test skipped); exposed so tests can check it on convex faces too.
void ear_clip_polygon(std::span<const glm::vec3> positions, std::span<const uint32_t> corners,
                      std::vector<glm::uvec3>& out);

}  // namespace refract::mesh
