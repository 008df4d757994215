// A glTF 2.0 scene (.glb, or .gltf with data: buffers) as a scene document: each mesh primitive of the
// default scene's node tree an object (world transform applied), its material's KHR_materials_* glass;
// KHR_lights_punctual lights; the first perspective camera. What has no meaning here is reported as a
// warning; what cannot be imported is a GltfError naming the glTF path. Nothing is stored: the caller
// stores the new meshes and then the document. docs/gltf.md states the mapping.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "gltf/glb_container.h"
#include "mesh/mesh.h"
#include "protocol/scene_document.h"

namespace refract::gltf {

// The mesh a reference ("sphere", "upload:NAME") names now; nullptr when none does.
using ExistingMesh = std::function<std::shared_ptr<const mesh::Mesh>(const std::string& reference)>;

struct ImportedMesh {
    std::string name;  // to upload as "upload:NAME"
    mesh::Mesh mesh;
};

struct ImportedScene {
    protocol::SceneDocument document;  // validated against the limits given
    std::vector<ImportedMesh> meshes;  // uploads the document names that do not exist yet
    std::vector<std::string> warnings;
};

// A glTF mesh becomes the built-in of its name when its geometry is that built-in's exactly, the upload of
// its name when that holds the same geometry, else a new upload under its name (with a hash of the
// geometry appended when the name is taken). Throws GltfError.
ImportedScene import_gltf(std::string_view bytes, const ExistingMesh& existing, const protocol::Limits& limits = {},
                          const ImportLimits& import_limits = {});

}  // namespace refract::gltf
