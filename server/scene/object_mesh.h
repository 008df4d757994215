// The object's mesh as a scene document names it: a built-in, an uploaded OBJ, or the sphere that a
// procedural lens (Luneburg, Maxwell) fills; and its placement in the world. One place for the CLI,
// the renderer and the tests.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"

namespace refract::scene {

using MeshLookup = std::function<std::shared_ptr<const mesh::Mesh>(const std::string& name)>;

// The untransformed mesh; uploads are looked up by name without the "upload:" prefix. Returns nullptr
// for an unknown upload or built-in. Built-ins are made once and shared.
std::shared_ptr<const mesh::Mesh> base_mesh(const protocol::SceneDocument& document, const MeshLookup& uploads);

// `base` scaled, rotated and moved as the document's object says.
mesh::Mesh world_mesh(const protocol::SceneDocument& document, const mesh::Mesh& base);

}  // namespace refract::scene
