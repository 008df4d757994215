// The scene's lattice, fitted to its document and its objects' world meshes.
#pragma once

#include <map>
#include <string>

#include "mesh/mesh.h"
#include "passes/grid_geometry.h"
#include "protocol/scene_document.h"
#include "render/medium_field.h"

namespace refract::scene {

// The scene's lattice: volume.bounds when given, else the box around every object's world bounds
// (`worlds`, procedural lenses' spheres of radius scale around position) and every volume's (its grid in
// `densities`, volume_world_box) grown by volume.margin, at
// volume.resolution along its longest side; that voxel divided by the smallest whole factor (at most
// passes::kMaxLightFactor) that gives every object with a resolution of its own at least that many voxels
// along the longest side of its own bounds.
passes::GridGeometry grid_for(const protocol::SceneDocument& document, const std::map<std::string, mesh::Mesh>& worlds,
                              const Densities& densities = {});

}  // namespace refract::scene
