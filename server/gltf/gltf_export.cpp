#include "gltf/gltf_export.h"

#include <algorithm>
#include <map>
#include <sstream>
#include <stdexcept>

#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "gltf/gltf_mapping.h"

namespace refract::gltf {
namespace {

using nlohmann::json;

tinygltf::Value value(const json& j) {
    if (j.is_object()) {
        tinygltf::Value::Object o;
        for (auto it = j.begin(); it != j.end(); ++it) o[it.key()] = value(it.value());
        return tinygltf::Value(std::move(o));
    }
    if (j.is_array()) {
        tinygltf::Value::Array a;
        for (const auto& item : j) a.push_back(value(item));
        return tinygltf::Value(std::move(a));
    }
    if (j.is_boolean()) return tinygltf::Value(j.get<bool>());
    if (j.is_number_integer()) return tinygltf::Value(j.get<int>());
    if (j.is_number()) return tinygltf::Value(j.get<double>());
    if (j.is_string()) return tinygltf::Value(j.get<std::string>());
    return {};
}

tinygltf::Value refract_extras(const json& member) { return value(json{{"refract", member}}); }

// A node placed by `m` (a rotation and a uniform scale, then a translation) as glTF's TRS.
tinygltf::Node placed_node(const std::string& name, const glm::dmat4& m) {
    tinygltf::Node node;
    node.name = name;
    const glm::dmat3 a(m);
    const double scale = glm::length(a[0]);
    const glm::dquat q = glm::quat_cast(a / scale);
    node.translation = {m[3].x, m[3].y, m[3].z};
    node.rotation = {q.x, q.y, q.z, q.w};
    if (scale != 1.0) node.scale = {scale, scale, scale};
    return node;
}

// Appends `bytes` to the buffer, 4-byte aligned, as a buffer view; returns its index.
int add_view(tinygltf::Model& model, const void* bytes, size_t size, int target) {
    auto& data = model.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data.size();
    view.byteLength = size;
    view.target = target;
    data.insert(data.end(), static_cast<const unsigned char*>(bytes), static_cast<const unsigned char*>(bytes) + size);
    model.bufferViews.push_back(view);
    return static_cast<int>(model.bufferViews.size() - 1);
}

// The mesh's vertices and triangles as accessors, and a triangle primitive reading them.
tinygltf::Primitive add_geometry(tinygltf::Model& model, const mesh::Mesh& m) {
    const mesh::MeshReport bounds = mesh::inspect(m);
    tinygltf::Accessor positions;
    positions.bufferView = add_view(model, m.positions.data(), m.positions.size() * sizeof(glm::vec3),
                                    TINYGLTF_TARGET_ARRAY_BUFFER);
    positions.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    positions.type = TINYGLTF_TYPE_VEC3;
    positions.count = m.positions.size();
    const glm::dvec3 lo(bounds.min), hi(bounds.max);
    positions.minValues = {lo.x, lo.y, lo.z};
    positions.maxValues = {hi.x, hi.y, hi.z};
    tinygltf::Accessor indices;
    indices.bufferView = add_view(model, m.triangles.data(), m.triangles.size() * sizeof(glm::uvec3),
                                  TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    indices.type = TINYGLTF_TYPE_SCALAR;
    indices.count = m.triangles.size() * 3;
    model.accessors.push_back(positions);
    model.accessors.push_back(indices);
    tinygltf::Primitive primitive;
    primitive.attributes["POSITION"] = static_cast<int>(model.accessors.size() - 2);
    primitive.indices = static_cast<int>(model.accessors.size() - 1);
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    return primitive;
}

void add_object(tinygltf::Model& model, std::map<std::string, tinygltf::Primitive>& geometry, const std::string& key,
                const protocol::Object& object, const BaseMesh& base_mesh) {
    if (object.index_field == protocol::IndexFieldKind::grid)
        throw std::invalid_argument("object '" + key + "' is an imported index grid, which has no glTF form");
    const auto base = base_mesh(object);
    if (!base) throw std::invalid_argument("object '" + key + "': no mesh " + object.mesh);
    const std::string reference = rendered_mesh(object);
    const std::string mesh_name = reference.rfind("upload:", 0) == 0 ? reference.substr(7) : reference;
    if (!geometry.contains(reference)) geometry[reference] = add_geometry(model, *base);
    tinygltf::Material material;
    material.name = key;
    material.pbrMetallicRoughness.metallicFactor = 0.0;
    material.pbrMetallicRoughness.roughnessFactor = 0.0;
    const json extensions = material_extensions(object, thickness(*base));
    for (auto it = extensions.begin(); it != extensions.end(); ++it) {
        material.extensions[it.key()] = value(it.value());
        if (std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), it.key()) == model.extensionsUsed.end())
            model.extensionsUsed.push_back(it.key());
    }
    model.materials.push_back(material);
    // A mesh of its own (its material is the object's), reading the geometry objects of one mesh share.
    tinygltf::Mesh gltf_mesh;
    gltf_mesh.name = mesh_name;
    gltf_mesh.primitives.push_back(geometry[reference]);
    gltf_mesh.primitives[0].material = static_cast<int>(model.materials.size() - 1);
    model.meshes.push_back(gltf_mesh);
    tinygltf::Node node = placed_node(key, object_matrix(object));
    node.mesh = static_cast<int>(model.meshes.size() - 1);
    node.extras = refract_extras(protocol::to_json(protocol::SceneDocument{.objects = {{key, object}}})["objects"][key]);
    model.nodes.push_back(node);
}

void add_light(tinygltf::Model& model, const std::string& key, const protocol::Light& light) {
    const json j = light_json(light);
    tinygltf::Light l;
    l.name = key;
    l.type = j["type"].get<std::string>();
    l.color = j["color"].get<std::vector<double>>();
    l.intensity = j["intensity"].get<double>();
    if (j.contains("spot")) {
        l.spot.innerConeAngle = j["spot"]["innerConeAngle"].get<double>();
        l.spot.outerConeAngle = j["spot"]["outerConeAngle"].get<double>();
    }
    model.lights.push_back(l);
    tinygltf::Node node = placed_node(key, light_matrix(light));
    node.extensions["KHR_lights_punctual"] = value({{"light", static_cast<int>(model.lights.size() - 1)}});
    node.extras = refract_extras(protocol::to_json(protocol::SceneDocument{.lights = {{key, light}}})["lights"][key]);
    model.nodes.push_back(node);
}

void add_camera(tinygltf::Model& model, const protocol::SceneDocument& document) {
    const json j = camera_json(document.camera, document.image)["perspective"];
    tinygltf::Camera camera;
    camera.type = "perspective";
    camera.perspective.yfov = j["yfov"].get<double>();
    camera.perspective.aspectRatio = j["aspectRatio"].get<double>();
    camera.perspective.znear = j["znear"].get<double>();
    camera.perspective.zfar = j["zfar"].get<double>();
    model.cameras.push_back(camera);
    tinygltf::Node node = placed_node("camera", camera_matrix(document.camera));
    node.camera = static_cast<int>(model.cameras.size() - 1);
    node.extras = refract_extras(protocol::to_json(document)["camera"]);
    model.nodes.push_back(node);
}

}  // namespace

std::string rendered_mesh(const protocol::Object& object) {
    const bool lens = object.index_field == protocol::IndexFieldKind::luneburg ||
                      object.index_field == protocol::IndexFieldKind::maxwell;
    return lens ? "sphere" : object.mesh;
}

std::string export_glb(const protocol::SceneDocument& document, const BaseMesh& base_mesh) {
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = "Refract";
    model.buffers.emplace_back();
    std::map<std::string, tinygltf::Primitive> geometry;  // by mesh reference: objects of one mesh share it
    for (const auto& [key, object] : document.objects) add_object(model, geometry, key, object, base_mesh);
    for (const auto& [key, light] : document.lights) add_light(model, key, light);
    if (!document.lights.empty() && model.extensionsUsed.end() ==
                                        std::find(model.extensionsUsed.begin(), model.extensionsUsed.end(), "KHR_lights_punctual"))
        model.extensionsUsed.push_back("KHR_lights_punctual");
    add_camera(model, document);
    tinygltf::Scene scene;
    scene.name = "Refract scene";
    for (size_t i = 0; i < model.nodes.size(); ++i) scene.nodes.push_back(static_cast<int>(i));
    json rest = protocol::to_json(document);
    for (const char* taken : {"camera", "lights", "objects"}) rest.erase(taken);
    scene.extras = refract_extras(rest);
    model.scenes.push_back(scene);
    model.defaultScene = 0;
    std::ostringstream out;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, out, false, true)) throw std::runtime_error("tinygltf could not write the scene");
    return out.str();
}

}  // namespace refract::gltf
