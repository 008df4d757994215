#include "render/object_mesh.h"

#include <map>
#include <mutex>
#include <stdexcept>

namespace refract::scene {
namespace {

glm::vec3 vec(const protocol::Vec3& v) {
    return {static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])};
}

std::shared_ptr<const mesh::Mesh> builtin(const std::string& name) {
    static std::mutex mutex;
    static std::map<std::string, std::shared_ptr<const mesh::Mesh>> cache;
    std::lock_guard lock(mutex);
    if (auto it = cache.find(name); it != cache.end()) return it->second;
    std::shared_ptr<const mesh::Mesh> m;
    if (name == "sphere") m = std::make_shared<mesh::Mesh>(mesh::make_sphere(5));
    else if (name == "cube") m = std::make_shared<mesh::Mesh>(mesh::make_cube());
    else if (name == "torus") m = std::make_shared<mesh::Mesh>(mesh::make_torus());
    else if (name == "prism") m = std::make_shared<mesh::Mesh>(mesh::make_prism());
    else if (name == "bunny") m = std::make_shared<mesh::Mesh>(mesh::make_blobby_bunny());
    else return nullptr;
    cache.emplace(name, m);
    return m;
}

}  // namespace

std::shared_ptr<const mesh::Mesh> base_mesh(const protocol::Object& object, const MeshLookup& uploads) {
    if (object.index_field == protocol::IndexFieldKind::luneburg ||
        object.index_field == protocol::IndexFieldKind::maxwell)
        return builtin("sphere");
    if (object.mesh.rfind("upload:", 0) == 0) return uploads ? uploads(object.mesh.substr(7)) : nullptr;
    return builtin(object.mesh);
}

mesh::Mesh world_mesh(const protocol::Object& object, const mesh::Mesh& base) {
    return mesh::transformed(base, static_cast<float>(object.scale), vec(object.rotation_deg), vec(object.position));
}

WorldMeshes world_meshes(const protocol::SceneDocument& document, const MeshLookup& uploads) {
    WorldMeshes worlds;
    for (const auto& [name, object] : document.objects) {
        if (object.index_field == protocol::IndexFieldKind::grid) continue;
        const auto base = base_mesh(object, uploads);
        if (!base) throw std::runtime_error("object '" + name + "': unknown mesh " + object.mesh);
        worlds.emplace(name, world_mesh(object, *base));
    }
    return worlds;
}

}  // namespace refract::scene
