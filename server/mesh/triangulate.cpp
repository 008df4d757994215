#include "mesh/triangulate.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>

namespace refract::mesh {
namespace {

// The face's corners in the plane its Newell normal is most aligned with, oriented so that the face's
// winding is counter-clockwise there (a positive signed area) whenever it has an area at all.
std::vector<glm::dvec2> project(std::span<const glm::vec3> positions, std::span<const uint32_t> corners) {
    const size_t n = corners.size();
    glm::dvec3 normal(0.0);
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 a(positions[corners[i]]), b(positions[corners[(i + 1) % n]]);
        normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    // Drop the axis with the largest normal component; the other two, cyclically next, keep the winding
    // when that component is positive, and are swapped when it is negative.
    int drop = 2;
    if (std::fabs(normal.x) >= std::fabs(normal.y) && std::fabs(normal.x) >= std::fabs(normal.z)) {
        drop = 0;
    } else if (std::fabs(normal.y) >= std::fabs(normal.z)) {
        drop = 1;
    }
    int u = (drop + 1) % 3, v = (drop + 2) % 3;
    if (normal[drop] < 0.0) std::swap(u, v);
    std::vector<glm::dvec2> out(n);
    for (size_t i = 0; i < n; ++i) {
        const glm::vec3& p = positions[corners[i]];
        out[i] = glm::dvec2(static_cast<double>(p[u]), static_cast<double>(p[v]));
    }
    return out;
}

// Twice the signed area of (a, b, c): positive for a left turn at b.
double turn(glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) {
    return (b.x - a.x) * (c.y - b.y) - (b.y - a.y) * (c.x - b.x);
}

// Coordinates are floats: a fine convex outline (a circle of 80,000 corners) dents inwards by a few units
// in the last place here and there. Turns that go right by less than this, relative to the outline's
// extent, count as straight on.
constexpr double kStraight = 16.0 * static_cast<double>(std::numeric_limits<float>::epsilon());

bool convex_projected(const std::vector<glm::dvec2>& p) {
    const size_t n = p.size();
    double extent = 0.0;
    for (const glm::dvec2& q : p) extent = std::max({extent, std::fabs(q.x), std::fabs(q.y)});
    const double tolerance = kStraight * extent;
    // Walk the edges of non-zero length: no turn may go right (beyond the tolerance), and all turns
    // together must make one full turn (a pentagram turns left everywhere too, but twice round).
    glm::dvec2 first(0.0), last(0.0);
    double total = 0.0;
    const auto visit = [&](glm::dvec2 edge) {
        const double cross = last.x * edge.y - last.y * edge.x;
        if (cross < -tolerance * (glm::length(last) + glm::length(edge))) return false;
        total += std::atan2(cross, glm::dot(last, edge));
        return true;
    };
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec2 edge = p[(i + 1) % n] - p[i];
        if (edge == glm::dvec2(0.0)) continue;
        if (last == glm::dvec2(0.0)) {
            first = last = edge;
            continue;
        }
        if (!visit(edge)) return false;
        last = edge;
    }
    if (last == glm::dvec2(0.0)) return true;  // every corner at one point
    if (!visit(first)) return false;
    // An outline with no area at all (on one line) turns by 0 or by multiples of pi; fanning it is harmless.
    return std::fabs(total - 2.0 * std::numbers::pi) < 0.5 * std::numbers::pi;
}

// Closed point-in-triangle test for a counter-clockwise triangle.
bool inside(glm::dvec2 a, glm::dvec2 b, glm::dvec2 c, glm::dvec2 p) {
    return turn(a, b, p) >= 0.0 && turn(b, c, p) >= 0.0 && turn(c, a, p) >= 0.0;
}

void fan(std::span<const uint32_t> corners, std::vector<glm::uvec3>& out) {
    for (size_t i = 1; i + 1 < corners.size(); ++i) out.emplace_back(corners[0], corners[i], corners[i + 1]);
}

// Ear clipping on a doubly linked ring. Every corner's ear flag is computed once (O(n) each), and after a
// cut only the two neighbours' flags change, so the whole face costs O(n^2), never more.
void ear_clip(const std::vector<glm::dvec2>& p, std::span<const uint32_t> corners,
              std::vector<glm::uvec3>& out) {
    const size_t n = p.size();
    std::vector<size_t> prev(n), next(n);
    for (size_t i = 0; i < n; ++i) {
        prev[i] = (i + n - 1) % n;
        next[i] = (i + 1) % n;
    }
    const auto convex = [&](size_t i) { return turn(p[prev[i]], p[i], p[next[i]]) > 0.0; };
    const auto is_ear = [&](size_t i) {
        if (!convex(i)) return false;
        const glm::dvec2 a = p[prev[i]], b = p[i], c = p[next[i]];
        for (size_t w = next[next[i]]; w != prev[i]; w = next[w]) {
            if (p[w] == a || p[w] == b || p[w] == c) continue;  // a repeated corner does not block
            if (inside(a, b, c, p[w])) return false;
        }
        return true;
    };
    std::vector<char> ear(n);
    for (size_t i = 0; i < n; ++i) ear[i] = is_ear(i);

    size_t remaining = n, v = 0, misses = 0;
    while (remaining > 3) {
        if (!ear[v] && misses < remaining) {
            v = next[v];
            ++misses;
            continue;
        }
        if (!ear[v]) {
            // A whole turn without an ear: the face is not simple. Cut a convex corner if there is one.
            for (size_t k = 0, w = v; k < remaining; ++k, w = next[w]) {
                if (convex(w)) {
                    v = w;
                    break;
                }
            }
        }
        const size_t a = prev[v], c = next[v];
        out.emplace_back(corners[a], corners[v], corners[c]);
        next[a] = c;
        prev[c] = a;
        --remaining;
        ear[a] = is_ear(a);
        ear[c] = is_ear(c);
        v = c;
        misses = 0;
    }
    out.emplace_back(corners[prev[v]], corners[v], corners[next[v]]);
}

}  // namespace

PlanarPolygon project_polygon(std::span<const glm::vec3> positions, std::span<const uint32_t> corners) {
    PlanarPolygon polygon;
    polygon.points = project(positions, corners);
    polygon.convex = polygon.points.size() <= 3 || convex_projected(polygon.points);
    return polygon;
}

void triangulate_polygon(const PlanarPolygon& polygon, std::span<const uint32_t> corners,
                         std::vector<glm::uvec3>& out) {
    if (corners.size() < 3) return;
    if (polygon.convex) {
        fan(corners, out);
    } else {
        ear_clip(polygon.points, corners, out);
    }
}

void ear_clip_polygon(const PlanarPolygon& polygon, std::span<const uint32_t> corners,
                      std::vector<glm::uvec3>& out) {
    if (corners.size() >= 3) ear_clip(polygon.points, corners, out);
}

}  // namespace refract::mesh
