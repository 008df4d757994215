// Triangulation of one polygon face of an OBJ file, in time linear in its corners when it is convex and
// quadratic (bounded by the caller) when it is not.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <vector>

namespace refract::mesh {

// One polygon face projected onto the plane its Newell normal is most aligned with, oriented so that its
// winding is counter-clockwise there; O(n).
struct PlanarPolygon {
    std::vector<glm::dvec2> points;  // one per corner
    // Every turn goes left or straight on (float rounding tolerated) and the boundary winds once.
    bool convex = false;
};
PlanarPolygon project_polygon(std::span<const glm::vec3> positions, std::span<const uint32_t> corners);

// Appends n - 2 triangles (indices taken from `corners`, in the face's winding) that cover the polygon.
// A convex face is fanned from its first corner in O(n); any other face is ear-clipped in O(n^2). A
// self-intersecting or degenerate face still gets n - 2 triangles (where no ear exists a convex corner,
// else any corner, is cut off), which may overlap.
void triangulate_polygon(const PlanarPolygon& polygon, std::span<const uint32_t> corners,
                         std::vector<glm::uvec3>& out);

// Ear clipping only, whether convex or not (tests compare it with the fan).
void ear_clip_polygon(const PlanarPolygon& polygon, std::span<const uint32_t> corners,
                      std::vector<glm::uvec3>& out);

}  // namespace refract::mesh
