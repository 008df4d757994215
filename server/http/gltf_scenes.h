// Scenes as glTF over HTTP: a glTF body made a scene (its new meshes uploaded as the OBJ uploads are),
// and a scene written as a .glb. The mapping itself is gltf/; this is what it takes from the store.
#pragma once

#include <string>
#include <vector>

#include "http/service.h"

namespace refract::http {

struct GltfImport {
    scene::SceneSnapshot created;
    std::vector<std::string> meshes;    // uploads this import made (by name)
    std::vector<std::string> warnings;  // what the glTF says that has no meaning here
};

// Creates scene `id` (empty: a random id) from a .glb or .gltf body. The document is mapped and
// validated before anything is stored; then the new meshes are uploaded and the scene created, and if
// that fails, the meshes this import uploaded are removed again: a refused import leaves nothing.
// Throws gltf::GltfError, mesh::MeshError, scene::StoreError, protocol::ValidationError (an environment
// image the scene's extras name that the store does not have).
GltfImport import_gltf_scene(Service& service, const std::string& id, const std::string& body);

// The scene's document as a .glb. Throws std::invalid_argument for a scene glTF cannot hold.
std::string export_gltf_scene(Service& service, const protocol::SceneDocument& document);

}  // namespace refract::http
