// Fuzzes the glTF importer, gltf::import_gltf, on .glb and .gltf bytes. Invariants: only GltfError is
// thrown; an imported scene is a valid document; every mesh it uploads has its indices in range and
// finite coordinates; and its export imports back to the same document (the round trip is exact).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>

#include "fuzz_check.h"
#include "gltf/gltf_error.h"
#include "gltf/gltf_export.h"
#include "gltf/gltf_import.h"

using namespace refract;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const auto cube = std::make_shared<const mesh::Mesh>(mesh::make_cube());
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    std::map<std::string, std::shared_ptr<const mesh::Mesh>> meshes{{"cube", cube}};
    const auto existing = [&](const std::string& reference) -> std::shared_ptr<const mesh::Mesh> {
        const auto it = meshes.find(reference);
        return it == meshes.end() ? nullptr : it->second;
    };
    gltf::ImportedScene scene;
    try {
        scene = gltf::import_gltf(bytes, existing, {}, {.max_bytes = 1u << 16});
    } catch (const gltf::GltfError& e) {
        REFRACT_FUZZ_CHECK(std::string_view(e.what()).size() > 10);
        return 0;
    }
    REFRACT_FUZZ_CHECK(protocol::parse_scene(protocol::to_json(scene.document)) == scene.document);
    for (auto& m : scene.meshes) {
        for (const auto& t : m.mesh.triangles)
            for (int k = 0; k < 3; ++k) REFRACT_FUZZ_CHECK(t[k] < m.mesh.positions.size());
        for (const auto& p : m.mesh.positions)
            for (int k = 0; k < 3; ++k) REFRACT_FUZZ_CHECK(std::isfinite(p[k]));
        meshes["upload:" + m.name] = std::make_shared<const mesh::Mesh>(std::move(m.mesh));
    }
    // Built-in meshes other than the cube are never matched here (the lookup has only the cube), so
    // a lens (which renders the sphere) has no mesh to export: skip the round trip for those.
    for (const auto& [name, object] : scene.document.objects)
        if (!existing(gltf::rendered_mesh(object))) return 0;
    const std::string glb =
        gltf::export_glb(scene.document, [&](const protocol::Object& o) { return existing(gltf::rendered_mesh(o)); });
    const gltf::ImportedScene back = gltf::import_gltf(glb, existing);
    REFRACT_FUZZ_CHECK(back.document == scene.document);
    REFRACT_FUZZ_CHECK(back.meshes.empty());
    return 0;
}
