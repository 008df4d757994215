#include "http/gltf_scenes.h"

#include "gltf/gltf_export.h"
#include "gltf/gltf_import.h"
#include "render/object_mesh.h"

namespace refract::http {
namespace {

// The mesh a reference names: a built-in, or an upload in the store.
std::shared_ptr<const mesh::Mesh> existing_mesh(Service& service, const std::string& reference) {
    protocol::Object object;
    object.mesh = reference;
    return scene::base_mesh(object, [&](const std::string& name) { return service.store().mesh(name); });
}

}  // namespace

GltfImport import_gltf_scene(Service& service, const std::string& id, const std::string& body) {
    scene::Store& store = service.store();
    gltf::ImportLimits limits;
    limits.max_bytes = service.config().max_body;
    gltf::ImportedScene imported = gltf::import_gltf(
        body, [&](const std::string& reference) { return existing_mesh(service, reference); }, store.limits(), limits);
    // Refused before anything is uploaded; the store checks both again when it creates the scene.
    if (!id.empty() && !scene::valid_scene_id(id))
        throw scene::StoreError(scene::StoreFailure::invalid, "scene id must match [a-z0-9-]{1,32}");
    if (!id.empty() && store.get(id)) throw scene::StoreError(scene::StoreFailure::taken, "scene '" + id + "' exists");
    GltfImport result;
    result.warnings = std::move(imported.warnings);
    try {
        for (const auto& m : imported.meshes) {
            store.put_mesh(m.name, mesh::to_obj(m.mesh, "from a glTF import", -1));
            result.meshes.push_back(m.name);
        }
        result.created = store.create(id, protocol::to_json(imported.document));
    } catch (...) {
        for (const auto& name : result.meshes) {
            try {
                store.remove_mesh(name);
            } catch (const scene::StoreError&) {
                // Named by a scene created meanwhile: it stays, as any upload in use does.
            }
        }
        throw;
    }
    if (!result.meshes.empty()) service.queue().forget_cached_frames();
    return result;
}

std::string export_gltf_scene(Service& service, const protocol::SceneDocument& document) {
    return gltf::export_glb(document, [&](const protocol::Object& object) {
        return scene::base_mesh(object, [&](const std::string& name) { return service.store().mesh(name); });
    });
}

}  // namespace refract::http
