// Refract's members in glTF's terms and back, in one place so that export and import cannot drift:
// placements as node matrices, lights as KHR_lights_punctual, glass as the KHR_materials_* extensions,
// the camera as a perspective camera. Units: metres both sides; angles degrees here, radians in glTF;
// light in W (Refract) and lm (glTF) at 683 lm/W, the luminous efficacy of 555 nm light that Blender's
// glTF add-on uses too.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"

namespace refract::gltf {

inline constexpr double kLumensPerWatt = 683.0;

// The node matrix that places an object: its position, rotation (XYZ Euler) and uniform scale.
glm::dmat4 object_matrix(const protocol::Object& object);
// The node matrix of a camera: at its position, looking down -Z at its target, +Y towards its up.
glm::dmat4 camera_matrix(const protocol::Camera& camera);
// The node matrix of a light: at its position, -Z along its direction.
glm::dmat4 light_matrix(const protocol::Light& light);

// The KHR_lights_punctual light (type, color, intensity in cd or lux, spot cones).
nlohmann::json light_json(const protocol::Light& light);
// The perspective camera (yfov, aspectRatio of the image, a znear).
nlohmann::json camera_json(const protocol::Camera& camera, const protocol::Image& image);
// The material's "extensions": transmission, ior, volume (`thickness`: the mesh's own extent),
// dispersion (when abbe > 0) and iridescence (when the film has a thickness).
nlohmann::json material_extensions(const protocol::Object& object, double thickness);
// The thicknessFactor of a mesh: its bounds' largest side, in its own coordinates.
double thickness(const mesh::Mesh& mesh);

// An object's placement from a node's world matrix, when it is a rotation, a uniform positive scale
// and a translation (to 1e-9); nullopt for shear, non-uniform or mirroring scale.
struct Placement {
    protocol::Vec3 position, rotation_deg;
    double scale = 1.0;
};
std::optional<Placement> placement(const glm::dmat4& world);

// A light from its KHR_lights_punctual JSON and its node's world matrix; `warnings` gets what glTF says
// that Refract cannot (a soft spot edge, a range). Throws std::invalid_argument for an unknown type.
protocol::Light light_from(const nlohmann::json& light, const glm::dmat4& world, std::vector<std::string>& warnings);
// A camera from its node's world matrix and yfov; the target 1 m ahead (glTF has no target).
protocol::Camera camera_from(const nlohmann::json& camera, const glm::dmat4& world);
// An object's glass from a material's extensions; `warnings` gets what is approximated, with `where`.
void glass_from(const nlohmann::json& extensions, protocol::Object& object, std::vector<std::string>& warnings,
                const std::string& where);

// Two JSON values equal but for numbers within 1e-9 (relative to their size, at least 1e-9 absolute).
bool near(const nlohmann::json& a, const nlohmann::json& b);
bool near(const glm::dmat4& a, const glm::dmat4& b);

}  // namespace refract::gltf
