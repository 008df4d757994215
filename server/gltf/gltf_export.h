// A scene document as a binary glTF 2.0 (.glb) that gltf_import reads back to the same document: each
// object a node with its mesh and a KHR_materials_* glass material, each light a node with its
// KHR_lights_punctual light, the camera a node; Refract's own record of each (and the scene's image,
// medium, volume, photons, floor and environment, which glTF cannot say) in extras.refract.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"

namespace refract::gltf {

// The untransformed mesh an object renders (a built-in, an upload); nullptr when none.
using BaseMesh = std::function<std::shared_ptr<const mesh::Mesh>(const protocol::Object& object)>;

// Throws std::invalid_argument for an object that has no mesh (an imported index grid) or whose mesh
// `base_mesh` cannot find.
std::string export_glb(const protocol::SceneDocument& document, const BaseMesh& base_mesh);

// The mesh reference an object renders: "sphere" for a Luneburg or Maxwell lens, else its own.
std::string rendered_mesh(const protocol::Object& object);

}  // namespace refract::gltf
