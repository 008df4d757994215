// An object's mesh as a scene document names it: a built-in, an uploaded OBJ, or the sphere that a
// procedural lens (Luneburg, Maxwell) fills; and its placement in the world. One place for the CLI,
// the renderer and the tests.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"

namespace refract::scene {

using MeshLookup = std::function<std::shared_ptr<const mesh::Mesh>(const std::string& name)>;

// The untransformed mesh; uploads are looked up by name without the "upload:" prefix. Returns nullptr
// for an unknown upload or built-in. Built-ins are made once and shared.
std::shared_ptr<const mesh::Mesh> base_mesh(const protocol::Object& object, const MeshLookup& uploads);

// `base` scaled, rotated and moved as the object says.
mesh::Mesh world_mesh(const protocol::Object& object, const mesh::Mesh& base);

// The objects' meshes in world space, by object name (an imported grid has none).
using WorldMeshes = std::map<std::string, mesh::Mesh>;

// Every object's mesh in world space, uploads found by `uploads` (which may throw for an unknown
// name). Throws std::runtime_error naming the object whose mesh is neither a built-in nor an upload.
WorldMeshes world_meshes(const protocol::SceneDocument& document, const MeshLookup& uploads);

}  // namespace refract::scene
