#include "mesh/mesh.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <span>
#include <sstream>
#include <system_error>
#include <unordered_map>
#include <utility>

#include "mesh/triangulate.h"

namespace refract::mesh {
namespace {

// ---------------------------------------------------------------------------------------------------------
// Small helpers

glm::dvec3 to_d(glm::vec3 v) {
    return glm::dvec3(v);
}

// Flips triangles of a convex, origin-centred shape so each faces away from the origin.
void orient_away_from_origin(Mesh& mesh) {
    for (auto& t : mesh.triangles) {
        const glm::dvec3 a = to_d(mesh.positions[t.x]), b = to_d(mesh.positions[t.y]),
                         c = to_d(mesh.positions[t.z]);
        if (glm::dot(glm::cross(b - a, c - a), a + b + c) < 0.0) std::swap(t.y, t.z);
    }
}

uint32_t to_index(size_t i) {
    return static_cast<uint32_t>(i);
}

std::string line_ref(size_t line) {
    return "line " + std::to_string(line);
}

// ---------------------------------------------------------------------------------------------------------
// OBJ reading, in one pass that refuses what a lenient reader would silently skip, zero or misread (faces
// with fewer than three corners, indices out of range, "nan"/"inf" or overflowing coordinates) and counts the
// triangles as it goes. Only 'v' and 'f' lines matter; everything else (normals, texture coordinates,
// groups, materials, lines, points) is ignored.

struct ObjFace {
    uint32_t corners;
    uint32_t line;
};

struct ObjScan {
    size_t vertices = 0;
    size_t faces = 0;
    size_t triangles = 0;  // after triangulation: corners - 2 per face
    std::vector<ObjFace> face_list;
    std::vector<glm::vec3> positions;  // every 'v'
    std::vector<uint32_t> corners;     // every face's corners, 0-based, face after face
};

bool is_blank(char c) {
    return c == ' ' || c == '\t';
}

// Splits `line` into whitespace-separated tokens (none for a '#' comment line).
void tokenize(std::string_view line, std::vector<std::string_view>& tokens) {
    tokens.clear();
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && is_blank(line[i])) ++i;
        if (i >= line.size() || (tokens.empty() && line[i] == '#')) break;  // comment line
        size_t j = i;
        while (j < line.size() && !is_blank(line[j])) ++j;
        tokens.push_back(line.substr(i, j - i));
        i = j;
    }
}

std::string quoted(std::string_view token) {
    constexpr size_t kMax = 40;
    std::string s(token.substr(0, kMax));
    if (token.size() > kMax) s += "...";
    return "'" + s + "'";
}

double parse_coordinate(std::string_view token, size_t line, const MeshLimits& limits) {
    std::string_view digits = token;
    if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
    double value = 0.0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (ec == std::errc::result_out_of_range) {
        throw MeshError("OBJ vertex coordinate " + quoted(token) + " on " + line_ref(line) +
                        " is out of range; coordinates must be finite numbers");
    }
    if (ec != std::errc() || end == digits.data()) {
        throw MeshError("OBJ vertex coordinate " + quoted(token) + " on " + line_ref(line) +
                        " is not a number");
    }
    if (!std::isfinite(value)) {
        throw MeshError("OBJ vertex coordinate " + quoted(token) + " on " + line_ref(line) +
                        " is NaN or infinite; coordinates must be finite numbers");
    }
    if (std::fabs(value) > static_cast<double>(limits.max_abs_coordinate)) {
        std::ostringstream msg;
        msg << "OBJ vertex coordinate " << quoted(token) << " on " << line_ref(line)
            << " is too large: coordinates must lie within +-" << limits.max_abs_coordinate
            << " (rescale the model)";
        throw MeshError(msg.str());
    }
    return value;
}

// Returns the corner's 0-based vertex index.
uint32_t face_corner(std::string_view token, size_t line, size_t vertices_so_far) {
    // "v", "v/vt", "v//vn" or "v/vt/vn": only the position index matters here.
    std::string_view index_text = token.substr(0, token.find('/'));
    if (!index_text.empty() && index_text.front() == '+') index_text.remove_prefix(1);
    long long index = 0;
    const auto [end, ec] = std::from_chars(index_text.data(), index_text.data() + index_text.size(), index);
    if (ec != std::errc() || end != index_text.data() + index_text.size()) {
        throw MeshError("OBJ face on " + line_ref(line) + " has an invalid vertex index " + quoted(token));
    }
    const auto n = static_cast<long long>(vertices_so_far);
    if (index == 0) {
        throw MeshError("OBJ face on " + line_ref(line) +
                        " uses vertex index 0; OBJ indices start at 1 (or count back from -1)");
    }
    if (index > n) {
        throw MeshError("OBJ face on " + line_ref(line) + " refers to vertex " + std::to_string(index) +
                        ", but only " + std::to_string(n) +
                        " vertices are defined before it (index out of range)");
    }
    if (index < -n) {
        throw MeshError("OBJ face on " + line_ref(line) + " uses relative vertex index " +
                        std::to_string(index) + ", which points before the first of the " +
                        std::to_string(n) + " vertices defined so far (index out of range)");
    }
    return static_cast<uint32_t>(index > 0 ? index - 1 : n + index);
}

void check_encoding(std::string_view text) {
    const auto byte = [&](size_t i) { return static_cast<unsigned char>(text[i]); };
    const bool utf16_bom =
        text.size() >= 2 && ((byte(0) == 0xFE && byte(1) == 0xFF) || (byte(0) == 0xFF && byte(1) == 0xFE));
    if (utf16_bom) {
        throw MeshError(
            "OBJ must be ASCII/UTF-8 text, but this file starts with a UTF-16/UTF-32 byte-order mark; "
            "re-save it as UTF-8 or ASCII");
    }
    if (text.find('\0') != std::string_view::npos) {
        throw MeshError(
            "OBJ must be ASCII/UTF-8 text, but this file contains NUL bytes (UTF-16/UTF-32 text or a binary "
            "file?); re-save it as UTF-8 or ASCII");
    }
    // Other control characters in more than a few places mean binary data rather than text.
    size_t control = 0;
    for (const char ch : text) {
        const auto c = static_cast<unsigned char>(ch);
        if (c < 0x20 && c != '\t' && c != '\n' && c != '\r' && c != '\v' && c != '\f' && c != 0x1A) ++control;
    }
    if (control > 16 && control * 100 > text.size()) {
        throw MeshError("OBJ must be ASCII/UTF-8 text, but this looks like a binary file");
    }
}

ObjScan scan_obj(std::string_view text, const MeshLimits& limits) {
    ObjScan scan;
    size_t line_number = 0;
    size_t pos = 0;
    std::vector<std::string_view> tokens;
    while (pos < text.size()) {
        // Lines end at "\n", "\r\n" or a lone "\r", as other OBJ readers accept.
        size_t end = pos;
        while (end < text.size() && text[end] != '\n' && text[end] != '\r') ++end;
        const std::string_view line = text.substr(pos, end - pos);
        ++line_number;
        pos = end;
        if (pos < text.size() && text[pos] == '\r') {
            ++pos;
            if (pos < text.size() && text[pos] == '\n') ++pos;
        } else if (pos < text.size()) {
            ++pos;  // '\n'
        }

        tokenize(line, tokens);
        if (tokens.empty()) continue;
        if (tokens[0] == "v") {
            if (tokens.size() < 4) {
                throw MeshError("OBJ vertex on " + line_ref(line_number) +
                                " has fewer than 3 coordinates (expected 'v x y z')");
            }
            if (scan.vertices == limits.max_vertices) {
                throw MeshError("OBJ has more than the limit of " + std::to_string(limits.max_vertices) +
                                " vertices (on " + line_ref(line_number) + "); simplify the model");
            }
            glm::vec3 p;
            for (int k = 0; k < 3; ++k) {
                p[k] = static_cast<float>(
                    parse_coordinate(tokens[static_cast<size_t>(k) + 1], line_number, limits));
            }
            scan.positions.push_back(p);
            ++scan.vertices;
        } else if (tokens[0] == "f") {
            const size_t corners = tokens.size() - 1;
            if (corners < 3) {
                throw MeshError("OBJ face on " + line_ref(line_number) + " has " + std::to_string(corners) +
                                " vertices; a face needs at least 3");
            }
            for (size_t k = 1; k < tokens.size(); ++k) {
                scan.corners.push_back(face_corner(tokens[k], line_number, scan.vertices));
            }
            ++scan.faces;
            scan.face_list.push_back({to_index(corners), to_index(line_number)});
            scan.triangles += corners - 2;
            if (scan.triangles > limits.max_triangles) {
                throw MeshError("OBJ has more than the limit of " + std::to_string(limits.max_triangles) +
                                " triangles (after triangulating polygons); simplify the model");
            }
        }
    }
    return scan;
}

// ---------------------------------------------------------------------------------------------------------
// Welding by exact position

struct PositionKey {
    std::array<uint32_t, 3> bits;
    bool operator==(const PositionKey&) const = default;
};

struct PositionKeyHash {
    size_t operator()(const PositionKey& k) const noexcept {
        uint64_t h = 1469598103934665603ull;
        for (const uint32_t b : k.bits) {
            h ^= b;
            h *= 1099511628211ull;
            h ^= h >> 29;
        }
        return static_cast<size_t>(h);
    }
};

PositionKey key_of(glm::vec3 p) {
    PositionKey key{};
    for (int i = 0; i < 3; ++i) {
        const float v = p[i] + 0.0f;  // -0 becomes +0
        uint32_t bits = 0;
        std::memcpy(&bits, &v, sizeof bits);
        key.bits[static_cast<size_t>(i)] = bits;
    }
    return key;
}

// Maps each vertex to the first vertex at exactly the same position.
std::vector<uint32_t> weld(const std::vector<glm::vec3>& positions) {
    std::unordered_map<PositionKey, uint32_t, PositionKeyHash> first;
    first.reserve(positions.size());
    std::vector<uint32_t> canonical(positions.size());
    for (size_t i = 0; i < positions.size(); ++i) {
        canonical[i] = first.try_emplace(key_of(positions[i]), to_index(i)).first->second;
    }
    return canonical;
}

// ---------------------------------------------------------------------------------------------------------
// Blobby bunny: ellipsoidal metaballs, polygonized by marching tetrahedra on a Kuhn-subdivided grid. Each
// cube splits into six tetrahedra along its main diagonal, so neighbouring cubes agree on their face
// diagonals and the result is a closed 2-manifold. Only + - * / are used, so the output is reproducible.

struct Blob {
    glm::dvec3 center;
    glm::dvec3 radii;
    // Rotation (cosine, sine) about X, then about Z, of the ellipsoid's axes.
    double cx = 1.0, sx = 0.0, cz = 1.0, sz = 0.0;
    double weight = 1.0;
};

constexpr double kIso = 0.421875;  // (1 - 1/4)^3: an isolated blob's surface is its ellipsoid

double blob_field(const Blob& b, glm::dvec3 p) {
    glm::dvec3 d = p - b.center;
    // Into the blob's frame: undo Z rotation, then X rotation.
    d = glm::dvec3(b.cz * d.x + b.sz * d.y, -b.sz * d.x + b.cz * d.y, d.z);
    d = glm::dvec3(d.x, b.cx * d.y + b.sx * d.z, -b.sx * d.y + b.cx * d.z);
    const glm::dvec3 q = d / b.radii;
    const double r2 = glm::dot(q, q);
    if (r2 >= 4.0) return 0.0;
    const double u = 1.0 - 0.25 * r2;
    return b.weight * u * u * u;
}

std::vector<Blob> bunny_blobs() {
    // Facing +X, Y up. (cos, sin) pairs come from Pythagorean triples so they are exact ratios.
    std::vector<Blob> blobs;
    blobs.push_back({{-0.15, -0.28, 0.0}, {0.58, 0.46, 0.44}, 1.0, 0.0, 0.96, 0.28, 1.0});  // body
    blobs.push_back({{-0.38, -0.48, 0.24}, {0.30, 0.24, 0.17}, 1.0, 0.0, 1.0, 0.0, 1.0});   // haunch
    blobs.push_back({{-0.38, -0.48, -0.24}, {0.30, 0.24, 0.17}, 1.0, 0.0, 1.0, 0.0, 1.0});  // haunch
    blobs.push_back({{0.36, 0.12, 0.0}, {0.30, 0.26, 0.25}, 1.0, 0.0, 1.0, 0.0, 1.0});      // head
    blobs.push_back({{0.60, 0.04, 0.0}, {0.14, 0.12, 0.13}, 1.0, 0.0, 1.0, 0.0, 1.0});      // snout
    // Ears: long, flat, tilted back (about Z) and splayed sideways (about X).
    blobs.push_back({{0.22, 0.58, 0.11}, {0.11, 0.33, 0.07}, 0.96, -0.28, 0.8, 0.6, 1.0});
    blobs.push_back(
        {{0.24, 0.56, -0.11}, {0.11, 0.32, 0.07}, 0.96, 0.28, 0.923076923076923, 0.384615384615385, 1.0});
    blobs.push_back({{-0.74, -0.16, 0.0}, {0.11, 0.11, 0.11}, 1.0, 0.0, 1.0, 0.0, 1.0});     // tail
    blobs.push_back({{0.30, -0.66, 0.15}, {0.16, 0.075, 0.085}, 1.0, 0.0, 1.0, 0.0, 1.0});   // paw
    blobs.push_back({{0.30, -0.66, -0.15}, {0.16, 0.075, 0.085}, 1.0, 0.0, 1.0, 0.0, 1.0});  // paw
    return blobs;
}

// The blobs' summed field, sampled at the nodes of a grid that covers every blob's support (2x radii)
// plus one cell, so that the grid's border lies outside the surface.
struct SampledField {
    glm::dvec3 lo{0.0};
    double cell = 0.0;
    std::array<size_t, 3> n{};  // nodes per axis
    std::vector<double> values;

    size_t node_id(size_t x, size_t y, size_t z) const { return (z * n[1] + y) * n[0] + x; }
    glm::dvec3 node_pos(size_t x, size_t y, size_t z) const {
        return lo + cell * glm::dvec3(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
    }
};

SampledField sample_blobs(const std::vector<Blob>& blobs, double cell) {
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (const Blob& b : blobs) {
        const double r = 2.0 * std::max({b.radii.x, b.radii.y, b.radii.z});
        lo = glm::min(lo, b.center - glm::dvec3(r));
        hi = glm::max(hi, b.center + glm::dvec3(r));
    }
    lo -= glm::dvec3(cell);
    SampledField field;
    field.lo = lo;
    field.cell = cell;
    for (int a = 0; a < 3; ++a) {
        field.n[static_cast<size_t>(a)] = static_cast<size_t>(std::ceil((hi[a] + cell - lo[a]) / cell)) + 1;
    }
    const std::array<size_t, 3>& n = field.n;
    field.values.resize(n[0] * n[1] * n[2]);
    for (size_t z = 0; z < n[2]; ++z) {
        for (size_t y = 0; y < n[1]; ++y) {
            for (size_t x = 0; x < n[0]; ++x) {
                const glm::dvec3 p = field.node_pos(x, y, z);
                double f = 0.0;
                for (const Blob& b : blobs) f += blob_field(b, p);
                field.values[field.node_id(x, y, z)] = f;
            }
        }
    }
    return field;
}

// Corner c of a cube: bit 0 = +x, bit 1 = +y, bit 2 = +z.
glm::ivec3 corner_offset(int c) {
    return glm::ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
}

// The step from corner `from` to corner `to`.
glm::ivec3 corner_step(int to, int from) {
    return corner_offset(to) - corner_offset(from);
}

int det(glm::ivec3 a, glm::ivec3 b, glm::ivec3 c) {
    return a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) + a.z * (b.x * c.y - b.y * c.x);
}

// Marching tetrahedra over a sampled field. Each cube the surface crosses splits into six tetrahedra,
// and each tetrahedron the surface crosses adds a triangle or a quad. The vertex on a grid edge is made
// once and shared by every face that crosses that edge, so the surface comes out closed.
class TetrahedraPolygonizer {
public:
    explicit TetrahedraPolygonizer(const SampledField& field) : field_(field) {}

    Mesh polygonize() {
        const std::array<size_t, 3>& n = field_.n;
        for (size_t z = 0; z + 1 < n[2]; ++z) {
            for (size_t y = 0; y + 1 < n[1]; ++y) {
                for (size_t x = 0; x + 1 < n[0]; ++x) polygonize_cube(x, y, z);
            }
        }
        return std::move(mesh_);
    }

private:
    // A cube's corners, by number (corner_offset): their nodes and positions.
    struct Cube {
        std::array<size_t, 8> id{};
        std::array<glm::dvec3, 8> pos{};
    };

    bool inside(size_t node) const { return field_.values[node] > kIso; }

    void polygonize_cube(size_t x, size_t y, size_t z) {
        Cube cube;
        bool any_in = false, any_out = false;
        for (int c = 0; c < 8; ++c) {
            const glm::ivec3 o = corner_offset(c);
            const size_t cx = x + static_cast<size_t>(o.x), cy = y + static_cast<size_t>(o.y),
                         cz = z + static_cast<size_t>(o.z);
            cube.id[static_cast<size_t>(c)] = field_.node_id(cx, cy, cz);
            cube.pos[static_cast<size_t>(c)] = field_.node_pos(cx, cy, cz);
            (inside(cube.id[static_cast<size_t>(c)]) ? any_in : any_out) = true;
        }
        if (!any_in || !any_out) return;
        // The Kuhn split: six tetrahedra around the main diagonal 0-7, one for each order of the axes.
        constexpr std::array<std::array<int, 3>, 6> kAxisOrders{
            {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
        for (const auto& order : kAxisOrders) {
            const int v1 = 1 << order[0], v2 = v1 | (1 << order[1]);
            polygonize_tetrahedron(cube, {0, v1, v2, 7});
        }
    }

    void polygonize_tetrahedron(const Cube& cube, const std::array<int, 4>& tet) {
        std::array<int, 4> in{}, out{};
        int n_in = 0, n_out = 0;
        for (const int c : tet) {
            if (inside(cube.id[static_cast<size_t>(c)])) {
                in[static_cast<size_t>(n_in++)] = c;
            } else {
                out[static_cast<size_t>(n_out++)] = c;
            }
        }
        if (n_in == 0 || n_out == 0) return;
        if (n_in == 1) {
            add_lone_corner(cube, in[0], {out[0], out[1], out[2]}, true);
        } else if (n_in == 3) {
            add_lone_corner(cube, out[0], {in[0], in[1], in[2]}, false);
        } else {
            add_quad(cube, in[0], in[1], out[0], out[1]);
        }
    }

    // One corner alone on its side (inside when `lone_inside`): a triangle across its three edges. The
    // sign of the corner tetrahedron's determinant fixes the winding, whatever the crossing points.
    void add_lone_corner(const Cube& cube, int lone, const std::array<int, 3>& others, bool lone_inside) {
        glm::uvec3 tri(edge_vertex(cube, lone, others[0]), edge_vertex(cube, lone, others[1]),
                       edge_vertex(cube, lone, others[2]));
        const int d =
            det(corner_step(others[0], lone), corner_step(others[1], lone), corner_step(others[2], lone));
        const bool outward = lone_inside ? d > 0 : d < 0;
        if (!outward) std::swap(tri.y, tri.z);
        mesh_.triangles.push_back(tri);
    }

    // Two corners on each side: the quad a-b-c-d around edges (i0,o0) (i0,o1) (i1,o1) (i1,o0), as two
    // triangles split along its shorter diagonal.
    void add_quad(const Cube& cube, int i0, int i1, int o0, int o1) {
        std::array<uint32_t, 4> q{edge_vertex(cube, i0, o0), edge_vertex(cube, i0, o1),
                                  edge_vertex(cube, i1, o1), edge_vertex(cube, i1, o0)};
        if (det(corner_step(o0, i0), corner_step(o1, i0), corner_step(i1, i0)) < 0) std::swap(q[1], q[3]);
        const auto p = [&](size_t k) { return to_d(mesh_.positions[q[k]]); };
        const double ac = glm::dot(p(2) - p(0), p(2) - p(0));
        const double bd = glm::dot(p(3) - p(1), p(3) - p(1));
        if (ac <= bd) {
            mesh_.triangles.emplace_back(q[0], q[1], q[2]);
            mesh_.triangles.emplace_back(q[0], q[2], q[3]);
        } else {
            mesh_.triangles.emplace_back(q[0], q[1], q[3]);
            mesh_.triangles.emplace_back(q[1], q[2], q[3]);
        }
    }

    // The vertex where the surface crosses the edge between corners `a` and `b` of `cube`.
    uint32_t edge_vertex(const Cube& cube, int a, int b) {
        return vertex_on_edge(cube.id[static_cast<size_t>(a)], cube.pos[static_cast<size_t>(a)],
                              cube.id[static_cast<size_t>(b)], cube.pos[static_cast<size_t>(b)]);
    }

    // The vertex on the grid edge between nodes `a` and `b`, made by the first face that crosses it.
    uint32_t vertex_on_edge(size_t a, glm::dvec3 pa, size_t b, glm::dvec3 pb) {
        if (a > b) {
            std::swap(a, b);
            std::swap(pa, pb);
        }
        const uint64_t key = (static_cast<uint64_t>(a) << 32) | static_cast<uint64_t>(b);
        const auto found = edge_vertices_.find(key);
        if (found != edge_vertices_.end()) return found->second;
        const double fa = field_.values[a], fb = field_.values[b];
        // Clamped away from the nodes so no two vertices can meet when rounded to 5 decimals.
        const double t = std::clamp((kIso - fa) / (fb - fa), 0.02, 0.98);
        const uint32_t index = to_index(mesh_.positions.size());
        mesh_.positions.push_back(glm::vec3(pa + t * (pb - pa)));
        edge_vertices_.emplace(key, index);
        return index;
    }

    const SampledField& field_;
    Mesh mesh_;
    std::unordered_map<uint64_t, uint32_t> edge_vertices_;  // by (lower node, higher node)
};

Mesh polygonize_blobs(const std::vector<Blob>& blobs, double cell) {
    const SampledField field = sample_blobs(blobs, cell);
    return TetrahedraPolygonizer(field).polygonize();
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// Built-ins

Mesh make_sphere(uint32_t subdivisions) {
    constexpr uint32_t kMaxSubdivisions = 8;
    if (subdivisions > kMaxSubdivisions) {
        throw MeshError("sphere subdivisions must be at most " + std::to_string(kMaxSubdivisions) + " (got " +
                        std::to_string(subdivisions) + ")");
    }
    // Icosahedron: cyclic permutations of (0, +-1, +-phi); faces are the triples of mutually nearest
    // vertices.
    const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<glm::dvec3> corners;
    for (int axis = 0; axis < 3; ++axis) {
        for (const double s1 : {-1.0, 1.0}) {
            for (const double s2 : {-phi, phi}) {
                glm::dvec3 p(0.0);
                p[(axis + 1) % 3] = s1;
                p[(axis + 2) % 3] = s2;
                corners.push_back(p);
            }
        }
    }
    Mesh mesh;
    for (const auto& c : corners) mesh.positions.push_back(glm::vec3(glm::normalize(c)));
    const auto adjacent = [&](size_t a, size_t b) {
        return std::fabs(glm::distance(corners[a], corners[b]) - 2.0) < 1e-9;  // edge length is 2
    };
    for (size_t a = 0; a < corners.size(); ++a) {
        for (size_t b = a + 1; b < corners.size(); ++b) {
            for (size_t c = b + 1; c < corners.size(); ++c) {
                if (adjacent(a, b) && adjacent(b, c) && adjacent(a, c)) {
                    mesh.triangles.emplace_back(to_index(a), to_index(b), to_index(c));
                }
            }
        }
    }
    orient_away_from_origin(mesh);

    for (uint32_t level = 0; level < subdivisions; ++level) {
        std::unordered_map<uint64_t, uint32_t> midpoint;
        const auto mid = [&](uint32_t a, uint32_t b) {
            const uint64_t key = (static_cast<uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
            const auto [it, inserted] = midpoint.try_emplace(key, to_index(mesh.positions.size()));
            if (inserted) {
                const glm::dvec3 m = to_d(mesh.positions[a]) + to_d(mesh.positions[b]);
                mesh.positions.push_back(glm::vec3(glm::normalize(m)));
            }
            return it->second;
        };
        std::vector<glm::uvec3> finer;
        finer.reserve(mesh.triangles.size() * 4);
        for (const auto& t : mesh.triangles) {
            const uint32_t ab = mid(t.x, t.y), bc = mid(t.y, t.z), ca = mid(t.z, t.x);
            finer.emplace_back(t.x, ab, ca);
            finer.emplace_back(t.y, bc, ab);
            finer.emplace_back(t.z, ca, bc);
            finer.emplace_back(ab, bc, ca);
        }
        mesh.triangles = std::move(finer);
    }
    return mesh;
}

Mesh make_cube() {
    Mesh mesh;
    for (int c = 0; c < 8; ++c) {
        mesh.positions.emplace_back((c & 1) ? 1.0f : -1.0f, (c & 2) ? 1.0f : -1.0f, (c & 4) ? 1.0f : -1.0f);
    }
    // Each face: the four corners with bit `axis` equal to `side`, in cyclic order.
    for (uint32_t axis = 0; axis < 3; ++axis) {
        const uint32_t u = 1u << ((axis + 1) % 3), v = 1u << ((axis + 2) % 3);
        for (uint32_t side = 0; side < 2; ++side) {
            const uint32_t base = side << axis;
            const uint32_t a = base, b = base | u, c = base | u | v, d = base | v;
            mesh.triangles.emplace_back(a, b, c);
            mesh.triangles.emplace_back(a, c, d);
        }
    }
    orient_away_from_origin(mesh);
    return mesh;
}

Mesh make_prism() {
    Mesh mesh;
    // Vertex 2 k + s: corner k of the triangle (apex first), on the end face at z = s ? 1 : -1.
    for (int k = 0; k < 3; ++k) {
        const float angle = glm::radians(90.0f + 120.0f * static_cast<float>(k));
        for (float z : {-1.0f, 1.0f}) mesh.positions.emplace_back(std::cos(angle), std::sin(angle), z);
    }
    mesh.triangles.emplace_back(0, 2, 4);  // the two end faces
    mesh.triangles.emplace_back(1, 3, 5);
    for (uint32_t k = 0; k < 3; ++k) {  // the three sides
        const uint32_t next = (k + 1) % 3;
        mesh.triangles.emplace_back(2 * k, 2 * next, 2 * next + 1);
        mesh.triangles.emplace_back(2 * k, 2 * next + 1, 2 * k + 1);
    }
    orient_away_from_origin(mesh);
    return mesh;
}

Mesh make_torus(uint32_t major_segments, uint32_t minor_segments) {
    if (major_segments < 3 || minor_segments < 3) {
        throw MeshError("torus needs at least 3 segments around each circle");
    }
    if (static_cast<uint64_t>(major_segments) * minor_segments > 4'000'000u) {
        throw MeshError("torus has too many segments (at most 4,000,000 vertices)");
    }
    constexpr double kMajor = 1.0, kMinor = 0.35;
    Mesh mesh;
    for (uint32_t i = 0; i < major_segments; ++i) {
        const double u = 2.0 * std::numbers::pi * i / major_segments;
        for (uint32_t j = 0; j < minor_segments; ++j) {
            const double v = 2.0 * std::numbers::pi * j / minor_segments;
            const double ring = kMajor + kMinor * std::cos(v);
            mesh.positions.emplace_back(static_cast<float>(ring * std::cos(u)),
                                        static_cast<float>(kMinor * std::sin(v)),
                                        static_cast<float>(ring * std::sin(u)));
        }
    }
    const auto at = [&](uint32_t i, uint32_t j) {
        return (i % major_segments) * minor_segments + j % minor_segments;
    };
    for (uint32_t i = 0; i < major_segments; ++i) {
        for (uint32_t j = 0; j < minor_segments; ++j) {
            // d/du x d/dv points inward here, so walk v first to face outward.
            const uint32_t a = at(i, j), b = at(i, j + 1), c = at(i + 1, j + 1), d = at(i + 1, j);
            mesh.triangles.emplace_back(a, b, c);
            mesh.triangles.emplace_back(a, c, d);
        }
    }
    return mesh;
}

Mesh make_blobby_bunny() {
    Mesh mesh = polygonize_blobs(bunny_blobs(), 0.04);
    // Fit: centre the bounding box at the origin, largest half-extent 1, round to 5 decimals.
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (const auto& p : mesh.positions) {
        lo = glm::min(lo, to_d(p));
        hi = glm::max(hi, to_d(p));
    }
    const glm::dvec3 center = 0.5 * (lo + hi);
    const glm::dvec3 half = 0.5 * (hi - lo);
    const double scale = 1.0 / std::max({half.x, half.y, half.z});
    for (auto& p : mesh.positions) {
        glm::dvec3 q = (to_d(p) - center) * scale;
        for (int a = 0; a < 3; ++a) q[a] = std::round(q[a] * 1e5) / 1e5 + 0.0;
        p = glm::vec3(q);
    }
    return mesh;
}

std::string to_obj(const Mesh& mesh, std::string_view comment, int decimals) {
    const bool shortest = decimals < 0;
    decimals = std::clamp(decimals, 0, 9);
    std::string out;
    out.reserve(mesh.positions.size() * 32 + mesh.triangles.size() * 24 + comment.size() + 64);
    size_t pos = 0;
    while (pos < comment.size()) {
        const size_t end = std::min(comment.find('\n', pos), comment.size());
        out += "# ";
        out += comment.substr(pos, end - pos);
        out += '\n';
        pos = end + 1;
    }
    char buf[64];
    const double unit = std::pow(10.0, decimals);
    for (const auto& p : mesh.positions) {
        out += 'v';
        for (int a = 0; a < 3; ++a) {
            double value = static_cast<double>(p[a]);
            if (shortest ? value == 0.0 : std::round(value * unit) == 0.0) value = 0.0;  // no "-0.00000"
            const auto [end, ec] =
                shortest ? std::to_chars(buf, buf + sizeof buf, static_cast<float>(value))
                         : std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed, decimals);
            out += ' ';
            if (ec == std::errc()) {
                out.append(buf, end);
            } else {
                out += '0';
            }
        }
        out += '\n';
    }
    for (const auto& t : mesh.triangles) {
        out += "f " + std::to_string(t.x + 1) + ' ' + std::to_string(t.y + 1) + ' ' +
               std::to_string(t.z + 1) + '\n';
    }
    return out;
}

// ---------------------------------------------------------------------------------------------------------
// OBJ

Mesh parse_obj(std::string_view obj_text, const MeshLimits& limits) {
    if (obj_text.size() > limits.max_bytes) {
        throw MeshError("OBJ is " + std::to_string(obj_text.size()) + " bytes, over the limit of " +
                        std::to_string(limits.max_bytes) + " bytes");
    }
    check_encoding(obj_text);
    if (obj_text.size() >= 3 && obj_text.substr(0, 3) == "\xEF\xBB\xBF")
        obj_text.remove_prefix(3);  // UTF-8 BOM
    if (obj_text.find_first_not_of(" \t\r\n\v\f") == std::string_view::npos) {
        throw MeshError("OBJ is empty: it has no vertices and no faces");
    }

    const ObjScan scan = scan_obj(obj_text, limits);
    if (scan.vertices == 0) {
        throw MeshError("OBJ has no vertices ('v x y z' lines); is it really a Wavefront OBJ file?");
    }
    if (scan.faces == 0) {
        throw MeshError(
            "OBJ has " + std::to_string(scan.vertices) +
            " vertices but no faces ('f' lines): point clouds and lines cannot be rendered, a closed "
            "triangle or polygon surface is needed");
    }

    const std::vector<glm::vec3>& all_positions = scan.positions;
    const size_t vertex_count = all_positions.size();

    // Triangulate (issue 20: a reader's ear clipping took 21 s for one face of 80,000 corners, and would take
    // most of an hour for 1 M). A convex polygon (checked in O(n)) is fanned in O(n), however large. Any
    // other polygon is ear-clipped in O(n^2), so such faces are refused beyond max_concave_polygon_corners,
    // and the sum of corners^2 over them beyond max_concave_polygon_work. The first pass checks that, in
    // time linear in the corners, before the second cuts a single polygon (with the defaults, ear clipping
    // takes 0.3 s at most on a 2-core CI machine).
    std::vector<uint8_t> convex(scan.face_list.size(), 1);
    uint64_t concave_work = 0;
    size_t offset = 0;
    for (size_t f = 0; f < scan.face_list.size(); ++f) {
        const ObjFace& face = scan.face_list[f];
        const std::span<const uint32_t> polygon(scan.corners.data() + offset, face.corners);
        offset += face.corners;
        if (face.corners == 3 || project_polygon(all_positions, polygon).convex) continue;
        convex[f] = 0;
        if (face.corners > limits.max_concave_polygon_corners) {
            throw MeshError("OBJ face on " + line_ref(face.line) + " is a non-convex polygon with " +
                            std::to_string(face.corners) + " corners, over the limit of " +
                            std::to_string(limits.max_concave_polygon_corners) +
                            " corners for a non-convex polygon; triangulate it before uploading");
        }
        concave_work += uint64_t{face.corners} * face.corners;
        if (concave_work > limits.max_concave_polygon_work) {
            throw MeshError("OBJ has too many large non-convex polygons (the face on " + line_ref(face.line) +
                            " takes the sum of corners^2 over them past the limit of " +
                            std::to_string(limits.max_concave_polygon_work) +
                            "); triangulate them before uploading");
        }
    }
    std::vector<glm::uvec3> triangles;
    triangles.reserve(scan.triangles);
    offset = 0;
    for (size_t f = 0; f < scan.face_list.size(); ++f) {
        const std::span<const uint32_t> polygon(scan.corners.data() + offset, scan.face_list[f].corners);
        offset += polygon.size();
        if (convex[f]) {
            for (size_t i = 1; i + 1 < polygon.size(); ++i)
                triangles.emplace_back(polygon[0], polygon[i], polygon[i + 1]);
        } else {
            triangulate_polygon(project_polygon(all_positions, polygon), polygon, triangles);
        }
    }
    const size_t triangle_count = triangles.size();
    if (triangle_count > limits.max_triangles) {
        throw MeshError("OBJ has " + std::to_string(triangle_count) + " triangles, over the limit of " +
                        std::to_string(limits.max_triangles) + "; simplify the model");
    }
    if (triangle_count == 0) {
        throw MeshError("OBJ has no usable faces (every face was degenerate or invalid)");
    }
    // Vertices some triangle uses get new indices in file order.
    std::vector<uint8_t> used(vertex_count, 0);
    for (const auto& t : triangles) used[t.x] = used[t.y] = used[t.z] = 1;
    std::vector<uint32_t> remap(vertex_count, 0);
    Mesh mesh;
    for (size_t v = 0; v < vertex_count; ++v) {
        if (!used[v]) continue;
        remap[v] = to_index(mesh.positions.size());
        mesh.positions.push_back(all_positions[v]);
    }
    mesh.triangles.reserve(triangles.size());
    for (const auto& t : triangles) mesh.triangles.emplace_back(remap[t.x], remap[t.y], remap[t.z]);
    return mesh;
}

Mesh load_obj_file(const std::string& path, const MeshLimits& limits) {
    std::error_code ec;
    const std::filesystem::path fs_path(path);
    const auto status = std::filesystem::status(fs_path, ec);
    if (ec || !std::filesystem::exists(status)) {
        throw MeshError("cannot read OBJ file '" + path +
                        "': " + (ec ? ec.message() : std::string("no such file")));
    }
    if (!std::filesystem::is_regular_file(status)) {
        throw MeshError("cannot read OBJ file '" + path + "': not a regular file");
    }
    const auto size = std::filesystem::file_size(fs_path, ec);
    if (ec) throw MeshError("cannot read OBJ file '" + path + "': " + ec.message());
    if (size > limits.max_bytes) {
        throw MeshError("OBJ file '" + path + "' is " + std::to_string(size) + " bytes, over the limit of " +
                        std::to_string(limits.max_bytes) + " bytes");
    }
    std::ifstream in(fs_path, std::ios::binary);
    if (!in) throw MeshError("cannot read OBJ file '" + path + "': cannot open it");
    std::string text(static_cast<size_t>(size), '\0');
    in.read(text.data(), static_cast<std::streamsize>(text.size()));
    if (static_cast<size_t>(in.gcount()) != text.size()) {
        throw MeshError("cannot read OBJ file '" + path + "': read failed");
    }
    try {
        return parse_obj(text, limits);
    } catch (const MeshError& e) {
        throw MeshError(path + ": " + e.what());
    }
}

// ---------------------------------------------------------------------------------------------------------
// Inspection and transforms

Bounds bounds(const Mesh& mesh) {
    Bounds b;
    for (const auto& p : mesh.positions) {
        b.min = glm::min(b.min, p);
        b.max = glm::max(b.max, p);
    }
    return b;
}

MeshReport inspect(const Mesh& mesh) {
    MeshReport report;
    report.vertices = mesh.positions.size();
    report.triangles = mesh.triangles.size();
    if (!mesh.positions.empty()) {
        const Bounds box = bounds(mesh);
        report.min = box.min;
        report.max = box.max;
    }

    const std::vector<uint32_t> canonical = weld(mesh.positions);
    std::vector<uint64_t> edges;
    edges.reserve(mesh.triangles.size() * 3);
    const size_t n = mesh.positions.size();
    for (const auto& t : mesh.triangles) {
        if (t.x >= n || t.y >= n || t.z >= n) {
            ++report.degenerate_triangles;  // not a triangle at all
            continue;
        }
        const uint32_t a = canonical[t.x], b = canonical[t.y], c = canonical[t.z];
        if (a == b || b == c || a == c) {
            ++report.degenerate_triangles;
            continue;  // no meaningful edges
        }
        const glm::dvec3 pa = to_d(mesh.positions[a]), pb = to_d(mesh.positions[b]),
                         pc = to_d(mesh.positions[c]);
        const double twice_area = glm::length(glm::cross(pb - pa, pc - pa));
        const double longest2 =
            std::max({glm::dot(pb - pa, pb - pa), glm::dot(pc - pb, pc - pb), glm::dot(pa - pc, pa - pc)});
        if (!(twice_area > 1e-7 * longest2)) ++report.degenerate_triangles;
        for (const auto& [u, v] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
            edges.push_back((static_cast<uint64_t>(std::min(u, v)) << 32) | std::max(u, v));
        }
    }
    std::sort(edges.begin(), edges.end());
    for (size_t i = 0; i < edges.size();) {
        size_t j = i;
        while (j < edges.size() && edges[j] == edges[i]) ++j;
        const size_t uses = j - i;
        if (uses == 1) ++report.boundary_edges;
        if (uses >= 3) ++report.non_manifold_edges;
        i = j;
    }
    return report;
}

glm::dmat3 rotation(glm::dvec3 rotation_deg) {
    const glm::dvec3 r = rotation_deg * (std::numbers::pi / 180.0);
    const double cx = std::cos(r.x), sx = std::sin(r.x), cy = std::cos(r.y), sy = std::sin(r.y),
                 cz = std::cos(r.z), sz = std::sin(r.z);
    // glm matrices are column-major: glm::dmat3(col0, col1, col2).
    const glm::dmat3 rx(glm::dvec3(1, 0, 0), glm::dvec3(0, cx, sx), glm::dvec3(0, -sx, cx));
    const glm::dmat3 ry(glm::dvec3(cy, 0, -sy), glm::dvec3(0, 1, 0), glm::dvec3(sy, 0, cy));
    const glm::dmat3 rz(glm::dvec3(cz, sz, 0), glm::dvec3(-sz, cz, 0), glm::dvec3(0, 0, 1));
    return rz * ry * rx;
}

Mesh transformed(const Mesh& mesh, float scale, glm::vec3 rotation_deg, glm::vec3 translation) {
    const glm::dmat3 m = rotation(rotation_deg) * static_cast<double>(scale);
    const glm::dvec3 t(translation);

    Mesh out;
    out.positions.reserve(mesh.positions.size());
    for (const auto& p : mesh.positions) out.positions.push_back(glm::vec3(m * to_d(p) + t));
    out.triangles = mesh.triangles;
    if (scale < 0.0f) {
        for (auto& tri : out.triangles) std::swap(tri.y, tri.z);
    }
    return out;
}

double signed_volume(const Mesh& mesh) {
    double six_volume = 0.0;
    const size_t n = mesh.positions.size();
    for (const auto& t : mesh.triangles) {
        if (t.x >= n || t.y >= n || t.z >= n) continue;
        six_volume += glm::dot(to_d(mesh.positions[t.x]),
                               glm::cross(to_d(mesh.positions[t.y]), to_d(mesh.positions[t.z])));
    }
    return six_volume / 6.0;
}

}  // namespace refract::mesh
