// Fuzzes the OBJ reader, mesh::parse_obj, with small limits so that every limit can be reached.
// Invariants: only MeshError is thrown; an accepted mesh has every index in range, every vertex used,
// finite coordinates within the limit, no more triangles than the limit; inspect() runs on it; and its
// to_obj() text parses back to the same triangles and (to printing precision) the same positions.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "fuzz_check.h"
#include "mesh/mesh.h"

using namespace refract::mesh;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    MeshLimits limits;
    limits.max_bytes = 1u << 16;
    limits.max_triangles = 4096;
    limits.max_concave_polygon_corners = 256;
    limits.max_concave_polygon_work = 4 * 256 * 256;
    limits.max_abs_coordinate = 1e4f;
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    Mesh mesh;
    try {
        mesh = parse_obj(text, limits);
    } catch (const MeshError& e) {
        REFRACT_FUZZ_CHECK(std::string_view(e.what()).size() > 10);
        return 0;
    }
    REFRACT_FUZZ_CHECK(!mesh.triangles.empty());
    REFRACT_FUZZ_CHECK(mesh.triangles.size() <= limits.max_triangles);
    std::vector<bool> used(mesh.positions.size(), false);
    for (const auto& t : mesh.triangles) {
        for (int k = 0; k < 3; ++k) {
            REFRACT_FUZZ_CHECK(t[k] < mesh.positions.size());
            used[t[k]] = true;
        }
    }
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
        REFRACT_FUZZ_CHECK(used[v]);
        for (int a = 0; a < 3; ++a) {
            const float c = mesh.positions[v][a];
            REFRACT_FUZZ_CHECK(std::isfinite(c) && std::fabs(c) <= limits.max_abs_coordinate);
        }
    }
    const MeshReport report = inspect(mesh);
    REFRACT_FUZZ_CHECK(report.triangles == mesh.triangles.size() && report.vertices == mesh.positions.size());

    MeshLimits text_limits = limits;
    text_limits.max_bytes = 64u << 20;  // to_obj() text is longer than the input
    const Mesh back = parse_obj(to_obj(mesh, "round trip", 9), text_limits);
    REFRACT_FUZZ_CHECK(back.triangles == mesh.triangles);
    REFRACT_FUZZ_CHECK(back.positions.size() == mesh.positions.size());
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
        for (int a = 0; a < 3; ++a) {
            const double was = static_cast<double>(mesh.positions[v][a]);
            const double now = static_cast<double>(back.positions[v][a]);
            REFRACT_FUZZ_CHECK(std::fabs(now - was) <= 1e-9 + 1e-6 * std::fabs(was));
        }
    }
    return 0;
}
