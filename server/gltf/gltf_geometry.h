// A glTF's geometry read defensively: the model loaded from memory with no file access and no image
// decoded, node transforms checked finite, each primitive's accessors checked against their buffer
// views and buffers before a byte is read.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include <glm/glm.hpp>
#include <tiny_gltf.h>

#include "mesh/mesh.h"

namespace refract::gltf {

// Loads bytes that passed checked_json. Throws GltfError at "" with tinygltf's message.
tinygltf::Model load_model(std::string_view bytes);

// The node's own transform (matrix, or translation * rotation * scale). Throws GltfError at the node's
// path for a value that is not finite or a zero rotation quaternion.
glm::dmat4 local_matrix(const tinygltf::Node& node, const std::string& path);

// The primitive's triangles (triangles, strips and fans, indexed or not) with unused vertices dropped;
// nullopt for points and lines, which enclose nothing. Throws GltfError at `path` (the primitive's) for
// a missing POSITION, an accessor or buffer view past its buffer, an index past the vertices, a
// coordinate that is not finite, or more than `limits` allow.
std::optional<mesh::Mesh> primitive_mesh(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                         const std::string& path, const mesh::MeshLimits& limits = {});

}  // namespace refract::gltf
