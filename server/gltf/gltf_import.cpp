#include "gltf/gltf_import.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include <nlohmann/json.hpp>

#include "gltf/gltf_error.h"
#include "gltf/gltf_export.h"
#include "gltf/gltf_geometry.h"
#include "gltf/gltf_mapping.h"

namespace refract::gltf {
namespace {

using nlohmann::json;

// The five material extensions Refract writes and reads; any other has no meaning here.
constexpr const char* kGlassExtensions[] = {"KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume",
                                            "KHR_materials_dispersion", "KHR_materials_iridescence"};

json parsed(const std::string& text) {
    json j = text.empty() ? json::object() : json::parse(text, nullptr, false);
    return j.is_object() ? j : json::object();
}

// The Refract member an exporter left in `extras.refract`, or null.
json refract_extras(const std::string& extras_json) {
    const json extras = parsed(extras_json);
    const auto it = extras.find("refract");
    return it != extras.end() && it->is_object() ? *it : json();
}

std::string hash_suffix(const mesh::Mesh& m) {
    uint64_t h = 1469598103934665603ull;  // FNV-1a over the vertex and index bytes
    const auto mix = [&](const void* data, size_t size) {
        const auto* bytes = static_cast<const unsigned char*>(data);
        for (size_t i = 0; i < size; ++i) h = (h ^ bytes[i]) * 1099511628211ull;
    };
    mix(m.positions.data(), m.positions.size() * sizeof(glm::vec3));
    mix(m.triangles.data(), m.triangles.size() * sizeof(glm::uvec3));
    char text[12];
    std::snprintf(text, sizeof text, "-%08x", static_cast<unsigned>(h >> 32));
    return text;
}

bool same_mesh(const mesh::Mesh& a, const mesh::Mesh& b) {
    return a.positions == b.positions && a.triangles == b.triangles;
}

// `wanted` if it is a valid name not yet in `taken`, else `fallback` numbered until it is free.
template <typename Map>
std::string free_key(const Map& taken, const std::string& wanted, const std::string& fallback) {
    if (protocol::valid_name(wanted) && !taken.contains(wanted)) return wanted;
    const std::string base = protocol::valid_name(wanted) && wanted.size() < 56 ? wanted : fallback;
    for (size_t n = 1;; ++n)
        if (!taken.contains(base + "-" + std::to_string(n))) return base + "-" + std::to_string(n);
}

class Importer {
public:
    Importer(const tinygltf::Model& model, const ExistingMesh& existing, const protocol::Limits& limits)
        : model_(model), existing_(existing), limits_(limits) {}

    ImportedScene run() {
        const int scene = model_.defaultScene >= 0 ? model_.defaultScene : 0;
        if (static_cast<size_t>(scene) >= model_.scenes.size())
            throw GltfError("/scenes", "no scene to import (a glTF without scenes shows nothing)");
        scene_path_ = "/scenes/" + std::to_string(scene);
        warn_unused_features();
        visit_tree(model_.scenes[static_cast<size_t>(scene)].nodes);
        return assemble(refract_extras(model_.scenes[static_cast<size_t>(scene)].extras_json_string));
    }

private:
    void warn_unused_features() {
        if (!model_.textures.empty())
            warn("/textures", std::to_string(model_.textures.size()) +
                                  " texture(s) have no meaning here: each object's glass is uniform");
        if (!model_.skins.empty()) warn("/skins", "skins have no meaning here: meshes are taken in their bind pose");
        if (!model_.animations.empty()) warn("/animations", "animations are not imported (refract animate takes keyframes)");
    }

    void warn(const std::string& path, const std::string& what) { out_.warnings.push_back(path + ": " + what); }

    // Depth first in the scene's order, with an explicit stack: a hostile chain of nodes cannot exhaust
    // the call stack, and a node reached twice (glTF's hierarchy is a tree) is refused.
    void visit_tree(const std::vector<int>& roots) {
        std::vector<std::pair<int, glm::dmat4>> stack;
        for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.emplace_back(*it, glm::dmat4(1.0));
        std::set<int> seen;
        while (!stack.empty()) {
            const auto [index, parent] = stack.back();
            stack.pop_back();
            const std::string path = "/nodes/" + std::to_string(index);
            if (index < 0 || static_cast<size_t>(index) >= model_.nodes.size()) throw GltfError(path, "no such node");
            if (!seen.insert(index).second) throw GltfError(path, "reached twice: glTF's node hierarchy must be a tree");
            const tinygltf::Node& node = model_.nodes[static_cast<size_t>(index)];
            const glm::dmat4 world = parent * local_matrix(node, path);
            for (int c = 0; c < 4; ++c)
                for (int r = 0; r < 4; ++r)
                    if (!std::isfinite(world[c][r])) throw GltfError(path, "its world transform is not finite");
            visit(node, index, path, world);
            for (auto it = node.children.rbegin(); it != node.children.rend(); ++it) stack.emplace_back(*it, world);
        }
    }

    void visit(const tinygltf::Node& node, int index, const std::string& path, const glm::dmat4& world) {
        if (node.skin >= 0) warn(path + "/skin", "skinning has no meaning here: the mesh is taken in its bind pose");
        if (node.camera >= 0) add_camera(node, path, world);
        const json extensions = parsed(node.extensions_json_string);
        if (extensions.contains("KHR_lights_punctual")) add_light(node, path, extensions["KHR_lights_punctual"], world);
        if (node.mesh >= 0) add_primitives(node, index, path, world);
    }

    void add_camera(const tinygltf::Node& node, const std::string& path, const glm::dmat4& world) {
        if (static_cast<size_t>(node.camera) >= model_.cameras.size()) throw GltfError(path + "/camera", "no such camera");
        const tinygltf::Camera& c = model_.cameras[static_cast<size_t>(node.camera)];
        if (c.type != "perspective") return warn(path + "/camera", "an orthographic camera has no meaning here");
        if (camera_) return warn(path + "/camera", "only the first perspective camera is taken");
        json perspective = {{"yfov", c.perspective.yfov}, {"znear", c.perspective.znear}};
        if (c.perspective.aspectRatio > 0.0) perspective["aspectRatio"] = c.perspective.aspectRatio;
        if (c.perspective.zfar > 0.0) perspective["zfar"] = c.perspective.zfar;
        camera_gltf_ = {{"type", "perspective"}, {"perspective", perspective}};
        camera_world_ = world;
        camera_extras_ = refract_extras(node.extras_json_string);
        camera_ = camera_from(camera_gltf_, world);
        camera_path_ = path + "/camera";
    }

    void add_light(const tinygltf::Node& node, const std::string& path, const json& extension, const glm::dmat4& world) {
        const std::string where = path + "/extensions/KHR_lights_punctual";
        const int index = extension.is_object() ? extension.value("light", -1) : -1;
        if (index < 0 || static_cast<size_t>(index) >= model_.lights.size()) throw GltfError(where, "names no light");
        if (lights_.size() == protocol::kMaxLights)
            throw GltfError(where, "a light past the " + std::to_string(protocol::kMaxLights) + " a scene may hold");
        const tinygltf::Light& l = model_.lights[static_cast<size_t>(index)];
        json gltf_light = {{"type", l.type},
                           {"color", l.color.size() == 3 ? json(l.color) : json::array({1.0, 1.0, 1.0})},
                           {"intensity", l.intensity}};
        if (l.type == "spot")
            gltf_light["spot"] = {{"innerConeAngle", l.spot.innerConeAngle}, {"outerConeAngle", l.spot.outerConeAngle}};
        if (l.range > 0.0) gltf_light["range"] = l.range;
        std::vector<std::string> notes;
        protocol::Light light;
        try {
            light = light_from(gltf_light, world, notes);
        } catch (const std::invalid_argument& e) {
            throw GltfError(where, e.what());
        }
        for (const auto& note : notes) warn(where, note);
        // Refract's own record of the light is taken when it says what the glTF says.
        if (auto authored = member_from<protocol::Light>("lights", node.extras_json_string, path))
            if (near(light_json(*authored), gltf_light) && near(light_matrix(*authored), world)) light = *authored;
        const std::string key = free_key(lights_, node.name.empty() ? l.name : node.name, "light");
        lights_[key] = light;
        paths_["/lights/" + key] = where;
    }

    void add_primitives(const tinygltf::Node& node, int node_index, const std::string& path, const glm::dmat4& world) {
        if (static_cast<size_t>(node.mesh) >= model_.meshes.size()) throw GltfError(path + "/mesh", "no such mesh");
        const tinygltf::Mesh& gltf_mesh = model_.meshes[static_cast<size_t>(node.mesh)];
        for (size_t p = 0; p < gltf_mesh.primitives.size(); ++p) {
            const tinygltf::Primitive& primitive = gltf_mesh.primitives[p];
            const std::string where = "/meshes/" + std::to_string(node.mesh) + "/primitives/" + std::to_string(p);
            if (!primitive.targets.empty()) warn(where, "morph targets have no meaning here: the base shape is taken");
            std::optional<mesh::Mesh> geometry = primitive_mesh(model_, primitive, where);
            if (!geometry) {
                warn(where, "points and lines enclose nothing: skipped");
                continue;
            }
            if (objects_.size() == protocol::kMaxObjects)
                throw GltfError(where, "a primitive past the " + std::to_string(protocol::kMaxObjects) +
                                           " objects a scene may hold");
            const std::string single = gltf_mesh.name.empty() ? "mesh" + std::to_string(node.mesh) : gltf_mesh.name;
            const std::string mesh_name = gltf_mesh.primitives.size() == 1 ? single : single + "." + std::to_string(p);
            protocol::Object object = glass(primitive.material, where);
            if (const auto place = placement(world)) {
                object.position = place->position;
                object.rotation_deg = place->rotation_deg;
                object.scale = place->scale;
            } else {
                // Shear, non-uniform or mirroring scale: baked into a mesh of its own, placed at the origin.
                const glm::dmat3 a(world);
                for (auto& v : geometry->positions) v = glm::vec3(a * glm::dvec3(v) + glm::dvec3(world[3]));
                if (glm::determinant(a) < 0.0)
                    for (auto& t : geometry->triangles) std::swap(t.y, t.z);
                warn(path, "a transform with shear or non-uniform scale: baked into the mesh");
            }
            const double thick = thickness(*geometry);
            object.mesh = reference(mesh_name, std::move(*geometry));
            if (gltf_mesh.primitives.size() == 1)
                if (auto authored = member_from<protocol::Object>("objects", node.extras_json_string, path))
                    if (rendered_mesh(*authored) == object.mesh && near(object_matrix(*authored), world) &&
                        near(material_extensions(*authored, thick), glass_extensions(primitive.material)))
                        object = *authored;
            const std::string wanted = node.name.empty() ? mesh_name : node.name;
            const std::string key = free_key(objects_, gltf_mesh.primitives.size() == 1 ? wanted : wanted + "." + std::to_string(p),
                                             "object" + std::to_string(node_index));
            objects_[key] = object;
            paths_["/objects/" + key] = where;
        }
    }

    // The material's glass extensions (only those Refract reads), as the material wrote them.
    json glass_extensions(int material) const {
        json glass = json::object();
        if (material < 0 || static_cast<size_t>(material) >= model_.materials.size()) return glass;
        const json all = parsed(model_.materials[static_cast<size_t>(material)].extensions_json_string);
        for (const char* name : kGlassExtensions)
            if (all.contains(name)) glass[name] = all[name];
        return glass;
    }

    protocol::Object glass(int material, const std::string& where) {
        protocol::Object object;
        std::vector<std::string> notes;
        if (material >= 0 && static_cast<size_t>(material) >= model_.materials.size())
            throw GltfError(where + "/material", "no such material");
        const std::string material_path = material < 0 ? where : "/materials/" + std::to_string(material);
        glass_from(glass_extensions(material), object, notes, material_path);
        if (material >= 0) {
            const auto& base = model_.materials[static_cast<size_t>(material)].pbrMetallicRoughness.baseColorFactor;
            if (base.size() >= 3 && (base[0] != 1.0 || base[1] != 1.0 || base[2] != 1.0))
                notes.push_back(material_path + ": baseColorFactor has no meaning here: glass is tinted by "
                                                "KHR_materials_volume's attenuationColor");
        }
        for (const auto& note : notes)
            if (noted_.insert(note).second) out_.warnings.push_back(note);
        return object;
    }

    // The reference for a glTF mesh's geometry: a built-in or an upload it equals, else a new upload.
    std::string reference(const std::string& name, mesh::Mesh geometry) {
        const std::string base = protocol::valid_name(name) && name.size() <= 55 ? name : "mesh";
        if (const auto builtin = existing_(base); builtin && same_mesh(*builtin, geometry)) return base;
        for (const std::string& candidate : {base, base + hash_suffix(geometry)}) {
            const std::string ref = "upload:" + candidate;
            const auto it = chosen_.find(candidate);
            if (it != chosen_.end()) {
                if (same_mesh(it->second, geometry)) return ref;
                continue;
            }
            const auto stored = existing_(ref);
            if (stored && !same_mesh(*stored, geometry)) continue;
            chosen_.emplace(candidate, geometry);
            if (!stored) out_.meshes.push_back({candidate, std::move(geometry)});
            return ref;
        }
        throw GltfError("/meshes", "mesh name '" + base + "' and its hashed variant are both taken by other geometry");
    }

    // A member of `collection` from a node's extras.refract, validated as a document would be; nullopt
    // (with a warning) when it is not valid.
    template <typename Member>
    std::optional<Member> member_from(const char* collection, const std::string& extras_json, const std::string& path) {
        const json authored = refract_extras(extras_json);
        if (authored.is_null()) return std::nullopt;
        try {
            const protocol::SceneDocument d = protocol::parse_scene({{collection, {{"member", authored}}}}, limits_);
            if constexpr (std::is_same_v<Member, protocol::Light>) return d.lights.at("member");
            else return d.objects.at("member");
        } catch (const protocol::ValidationError& e) {
            warn(path + "/extras/refract", std::string("ignored: ") + e.what());
            return std::nullopt;
        }
    }

    ImportedScene assemble(const json& scene_extras) {
        if (objects_.empty()) throw GltfError(scene_path_, "no mesh primitives to import: a scene needs an object");
        harmonise_dispersion();
        protocol::SceneDocument parts;
        parts.objects = objects_;
        if (!lights_.empty()) parts.lights = lights_;
        else warn(scene_path_, "no KHR_lights_punctual light: the default spot light is taken");
        json document = protocol::to_json(parts);
        for (const char* section : {"image", "medium", "volume", "photons", "floor", "environment"}) {
            if (scene_extras.is_object() && scene_extras.contains(section)) document[section] = scene_extras[section];
            paths_[std::string("/") + section] = scene_path_ + "/extras/refract";
        }
        if (camera_) take_camera(document);
        else warn(scene_path_, "no perspective camera: the default camera is taken");
        try {
            out_.document = protocol::parse_scene(document, limits_);
        } catch (const protocol::ValidationError& e) {
            throw GltfError(gltf_path(e.pointer()), e.what());
        }
        return std::move(out_);
    }

    // The camera, and the image's aspect from the camera's when it has one.
    void take_camera(json& document) {
        protocol::Camera camera = *camera_;
        protocol::Image image;
        try {
            image = protocol::parse_scene({{"image", document.value("image", json::object())}}, limits_).image;
        } catch (const protocol::ValidationError&) {
            // Reported with its path when the whole document is parsed.
        }
        const json& perspective = camera_gltf_["perspective"];
        if (perspective.contains("aspectRatio") &&
            !near(json(static_cast<double>(image.width) / image.height), perspective["aspectRatio"])) {
            const double width = std::round(image.height * perspective["aspectRatio"].get<double>());
            image.width = static_cast<uint32_t>(std::clamp(width, 1.0, static_cast<double>(limits_.max_image_side)));
            document["image"] = protocol::to_json(protocol::SceneDocument{.image = image})["image"];
        }
        if (!camera_extras_.is_null()) {
            try {
                const protocol::Camera a = protocol::parse_scene({{"camera", camera_extras_}}, limits_).camera;
                if (near(camera_matrix(a), camera_world_) && near(camera_json(a, image), camera_gltf_)) camera = a;
            } catch (const protocol::ValidationError& e) {
                warn(camera_path_, std::string("extras.refract ignored: ") + e.what());
            }
        }
        document["camera"] = protocol::to_json(protocol::SceneDocument{.camera = camera})["camera"];
        paths_["/camera"] = camera_path_;
    }

    // Dispersion is one per scene: every object takes the first (by name) that disperses.
    void harmonise_dispersion() {
        const auto first = std::find_if(objects_.begin(), objects_.end(), [](const auto& o) { return o.second.abbe > 0.0; });
        if (first == objects_.end()) return;
        const double abbe = first->second.abbe;
        bool differed = false;
        for (auto& [name, object] : objects_) {
            differed = differed || object.abbe != abbe;
            object.abbe = abbe;
        }
        if (differed)
            warn(paths_["/objects/" + first->first],
                 "dispersion is one per scene here: every object takes this one's (Abbe number " + std::to_string(abbe) + ")");
    }

    // The glTF path of a document pointer: its member's primitive, light node or camera, and the pointer.
    std::string gltf_path(const std::string& pointer) const {
        std::string best;
        for (const auto& [prefix, path] : paths_)
            if ((pointer == prefix || pointer.rfind(prefix + "/", 0) == 0) && prefix.size() > best.size()) best = prefix;
        return best.empty() ? scene_path_ : paths_.at(best);
    }

    const tinygltf::Model& model_;
    const ExistingMesh& existing_;
    const protocol::Limits& limits_;
    ImportedScene out_;
    std::string scene_path_;
    std::map<std::string, protocol::Object> objects_;
    std::map<std::string, protocol::Light> lights_;
    std::map<std::string, std::string> paths_;  // document pointer prefix -> glTF path
    std::map<std::string, mesh::Mesh> chosen_;  // upload names this import uses, with their geometry
    std::set<std::string> noted_;               // material warnings already given
    std::optional<protocol::Camera> camera_;
    json camera_gltf_, camera_extras_;
    glm::dmat4 camera_world_{1.0};
    std::string camera_path_;
};

}  // namespace

ImportedScene import_gltf(std::string_view bytes, const ExistingMesh& existing, const protocol::Limits& limits,
                          const ImportLimits& import_limits) {
    checked_json(bytes, import_limits);
    const tinygltf::Model model = load_model(bytes);
    return Importer(model, existing, limits).run();
}

}  // namespace refract::gltf
