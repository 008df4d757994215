#include "gltf/gltf_mapping.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace refract::gltf {
namespace {

using nlohmann::json;

constexpr double kDegrees = 180.0 / std::numbers::pi;
constexpr double kTolerance = 1e-9;

glm::dvec3 dvec(const protocol::Vec3& v) { return {v[0], v[1], v[2]}; }

// A number derived from glTF's, rounded to 12 significant digits of `size` (its own, or its vector's
// largest): the 0.5 and 90 a file meant rather than 0.49999999999999994 and 90.00000000000001, and an
// exact 0 for an axis's 2e-16. Within float printing, and the same float for the renderer.
double tidy(double x, double size) {
    if (x == 0.0) return 0.0;  // never -0 (a white channel's -ln 1)
    if (!(size > 0.0) || !std::isfinite(x)) return x;
    const int decimals = std::clamp(11 - static_cast<int>(std::floor(std::log10(size))), 0, 330);
    char text[400];
    std::snprintf(text, sizeof text, "%.*f", decimals, x);
    const double y = std::strtod(text, nullptr);
    return y == 0.0 ? 0.0 : y;
}
double tidy(double x) { return tidy(x, std::fabs(x)); }

protocol::Vec3 vec3(const glm::dvec3& v) {
    const double size = std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    return {tidy(v.x, size), tidy(v.y, size), tidy(v.z, size)};
}
json rgb(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

// A node matrix from a position and a frame whose -Z is `forward` and whose +Y leans towards `up`.
glm::dmat4 frame_matrix(const glm::dvec3& position, const glm::dvec3& forward, const glm::dvec3& up) {
    const glm::dvec3 f = glm::normalize(forward);
    const glm::dvec3 r = glm::normalize(glm::cross(f, up));
    const glm::dvec3 u = glm::cross(r, f);
    return glm::dmat4(glm::dvec4(r, 0.0), glm::dvec4(u, 0.0), glm::dvec4(-f, 0.0), glm::dvec4(position, 1.0));
}

// A light's axis (a point light's zero direction points down, as any axis would do for it).
glm::dvec3 axis(const protocol::Light& light) {
    const glm::dvec3 d = dvec(light.direction);
    return glm::length(d) > 0.0 ? glm::normalize(d) : glm::dvec3(0.0, -1.0, 0.0);
}

double number(const json& j, const char* key, double fallback) {
    const auto it = j.find(key);
    return it != j.end() && it->is_number() ? it->get<double>() : fallback;
}

glm::dvec3 color(const json& j, const char* key, glm::dvec3 fallback) {
    const auto it = j.find(key);
    if (it == j.end() || !it->is_array() || it->size() != 3) return fallback;
    for (const auto& c : *it)
        if (!c.is_number()) return fallback;
    return {(*it)[0].get<double>(), (*it)[1].get<double>(), (*it)[2].get<double>()};
}

const json& member(const json& j, const char* key) {
    static const json empty = json::object();
    const auto it = j.find(key);
    return it != j.end() && it->is_object() ? *it : empty;
}

bool near(double a, double b) {
    return std::fabs(a - b) <= kTolerance * std::max({1.0, std::fabs(a), std::fabs(b)});
}

}  // namespace

glm::dmat4 object_matrix(const protocol::Object& object) {
    const glm::dmat3 r = mesh::rotation(dvec(object.rotation_deg)) * object.scale;
    return glm::dmat4(glm::dvec4(r[0], 0.0), glm::dvec4(r[1], 0.0), glm::dvec4(r[2], 0.0),
                      glm::dvec4(dvec(object.position), 1.0));
}

glm::dmat4 camera_matrix(const protocol::Camera& camera) {
    return frame_matrix(dvec(camera.position), dvec(camera.target) - dvec(camera.position), dvec(camera.up));
}

glm::dmat4 light_matrix(const protocol::Light& light) {
    const glm::dvec3 d = axis(light);
    const glm::dvec3 up = std::fabs(d.y) > 0.999 ? glm::dvec3(0.0, 0.0, -1.0) : glm::dvec3(0.0, 1.0, 0.0);
    return frame_matrix(dvec(light.position), d, up);
}

json light_json(const protocol::Light& light) {
    static const char* const kTypes[] = {"point", "spot", "directional"};
    // glTF's colour stays within [0, 1]: a brighter colour's excess moves into the intensity.
    glm::dvec3 c = dvec(light.color);
    const double peak = std::max({c.x, c.y, c.z});
    const double gain = peak > 1.0 ? peak : 1.0;
    c /= gain;
    json j = {{"type", kTypes[static_cast<int>(light.type)]},
              {"color", rgb(c)},
              {"intensity", light.intensity * gain * kLumensPerWatt}};
    if (light.type == protocol::LightType::spot) {
        // Refract's spot is a hard cone: the inner angle as close to the outer as glTF's "less than" allows.
        const double outer = light.cone_deg / kDegrees;
        j["spot"] = {{"innerConeAngle", std::nextafter(outer, 0.0)}, {"outerConeAngle", outer}};
    }
    return j;
}

json camera_json(const protocol::Camera& camera, const protocol::Image& image) {
    return {{"type", "perspective"},
            {"perspective",
             {{"yfov", camera.fov_deg / kDegrees},
              {"aspectRatio", static_cast<double>(image.width) / static_cast<double>(image.height)},
              {"znear", 0.01},
              {"zfar", 1e5}}}};  // ten times the farthest coordinate a document takes
}

double thickness(const mesh::Mesh& mesh) {
    const mesh::MeshReport report = mesh::inspect(mesh);
    const glm::vec3 size = report.max - report.min;
    return static_cast<double>(std::max({size.x, size.y, size.z}));
}

json material_extensions(const protocol::Object& object, double thickness) {
    json volume = {{"thicknessFactor", thickness}};
    // Light that travels attenuationDistance is tinted to attenuationColor: exp(-extinction * distance).
    // The distance is the most opaque channel's 1/e length, so no channel's colour underflows.
    const glm::dvec3 extinction = dvec(object.extinction);
    const double densest = std::max({extinction.x, extinction.y, extinction.z});
    if (densest > 0.0) {
        volume["attenuationDistance"] = 1.0 / densest;
        volume["attenuationColor"] = rgb(glm::exp(-extinction / densest));
    }
    json extensions = {{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                       {"KHR_materials_ior", {{"ior", object.ior}}},
                       {"KHR_materials_volume", volume}};
    if (object.abbe > 0.0) extensions["KHR_materials_dispersion"] = {{"dispersion", 20.0 / object.abbe}};
    const auto [thinnest, thickest] = std::minmax(object.film.top_nm, object.film.bottom_nm);
    if (thickest > 0.0)
        extensions["KHR_materials_iridescence"] = {{"iridescenceFactor", 1.0},
                                                   {"iridescenceIor", object.film.ior},
                                                   {"iridescenceThicknessMinimum", thinnest},
                                                   {"iridescenceThicknessMaximum", thickest}};
    return extensions;
}

std::optional<Placement> placement(const glm::dmat4& world) {
    const glm::dmat3 a(world);
    const double det = glm::determinant(a);
    if (!(det > 0.0)) return std::nullopt;
    const double scale = std::cbrt(det);
    const glm::dmat3 r = a / scale;
    const glm::dmat3 should_be_identity = glm::transpose(r) * r;
    for (int c = 0; c < 3; ++c)
        for (int row = 0; row < 3; ++row)
            if (!near(should_be_identity[c][row], c == row ? 1.0 : 0.0)) return std::nullopt;
    // r = Rz * Ry * Rx (mesh::rotation); glm is column-major, r[column][row].
    const double sy = std::clamp(-r[0][2], -1.0, 1.0);
    double x = 0.0, z = 0.0;
    if (std::fabs(sy) < 1.0 - 1e-12) {
        x = std::atan2(r[1][2], r[2][2]);
        z = std::atan2(r[0][1], r[0][0]);
    } else {
        z = std::atan2(-r[1][0], r[1][1]);  // gimbal lock: only x + z or x - z is defined; x is 0
    }
    return Placement{vec3(glm::dvec3(world[3])), vec3(glm::dvec3(x, std::asin(sy), z) * kDegrees), tidy(scale)};
}

protocol::Light light_from(const json& light, const glm::dmat4& world, std::vector<std::string>& warnings) {
    protocol::Light l;
    const std::string type = light.value("type", std::string());
    if (type == "point") l.type = protocol::LightType::point;
    else if (type == "spot") l.type = protocol::LightType::spot;
    else if (type == "directional") l.type = protocol::LightType::directional;
    else throw std::invalid_argument("unknown light type '" + type + "' (point, spot or directional)");
    l.position = vec3(glm::dvec3(world[3]));
    const glm::dvec3 forward = -glm::dvec3(world[2]);
    if (!(glm::length(forward) > 0.0)) throw std::invalid_argument("the light's node has no direction (zero scale)");
    l.direction = vec3(glm::normalize(forward));
    l.color = vec3(color(light, "color", glm::dvec3(1.0)));
    l.intensity = tidy(number(light, "intensity", 1.0) / kLumensPerWatt);
    const json& spot = member(light, "spot");
    const double outer = number(spot, "outerConeAngle", std::numbers::pi / 4.0);
    l.cone_deg = tidy(outer * kDegrees);
    if (l.type == protocol::LightType::spot && number(spot, "innerConeAngle", 0.0) < outer * (1.0 - 1e-6))
        warnings.push_back("innerConeAngle " + std::to_string(number(spot, "innerConeAngle", 0.0)) +
                           " (a soft edge) has no meaning here: the spot is a hard cone at its outerConeAngle");
    if (number(light, "range", 0.0) > 0.0)
        warnings.push_back("range has no meaning here: light falls off by the inverse square, without a cut-off");
    return l;
}

protocol::Camera camera_from(const json& camera, const glm::dmat4& world) {
    protocol::Camera c;
    const glm::dvec3 position(world[3]);
    c.position = vec3(position);
    c.target = vec3(position + glm::normalize(-glm::dvec3(world[2])));
    c.up = vec3(glm::normalize(glm::dvec3(world[1])));
    c.fov_deg = tidy(number(member(camera, "perspective"), "yfov", 0.0) * kDegrees);
    return c;
}

void glass_from(const json& extensions, protocol::Object& object, std::vector<std::string>& warnings,
                const std::string& where) {
    object.ior = number(member(extensions, "KHR_materials_ior"), "ior", 1.5);
    const double transmission = number(member(extensions, "KHR_materials_transmission"), "transmissionFactor", 0.0);
    if (transmission < 1.0)
        warnings.push_back(where + ": transmissionFactor " + std::to_string(transmission) +
                           " (not glass): imported as clear glass, which is all Refract renders");
    if (!extensions.contains("KHR_materials_volume"))
        warnings.push_back(where + ": no KHR_materials_volume (glTF's thin wall): imported as solid glass");
    const json& volume = member(extensions, "KHR_materials_volume");
    const double distance = number(volume, "attenuationDistance", std::numeric_limits<double>::infinity());
    const glm::dvec3 tint = color(volume, "attenuationColor", glm::dvec3(1.0));
    for (int c = 0; c < 3; ++c) {
        if (tint[c] > 0.0) {
            object.extinction[static_cast<size_t>(c)] = std::isfinite(distance) ? tidy(-std::log(tint[c]) / distance) : 0.0;
        } else {
            object.extinction[static_cast<size_t>(c)] = 1000.0;
            warnings.push_back(where + ": attenuationColor 0 (opaque) taken as extinction 1000/m, the most Refract takes");
        }
    }
    object.scattering = {0.0, 0.0, 0.0};  // glTF's volume only absorbs
    const double dispersion = number(member(extensions, "KHR_materials_dispersion"), "dispersion", 0.0);
    object.abbe = dispersion > 0.0 ? tidy(20.0 / dispersion) : 0.0;
    const json& film = member(extensions, "KHR_materials_iridescence");
    const double factor = number(film, "iridescenceFactor", 0.0);
    if (factor > 0.0) {
        object.film.ior = number(film, "iridescenceIor", 1.3);
        object.film.top_nm = object.film.bottom_nm = number(film, "iridescenceThicknessMaximum", 400.0);
        if (factor < 1.0)
            warnings.push_back(where + ": iridescenceFactor " + std::to_string(factor) + " taken as 1 (a film covers the whole object)");
        if (film.contains("iridescenceThicknessTexture"))
            warnings.push_back(where + ": the iridescence thickness texture has no meaning here: the film is "
                                       "iridescenceThicknessMaximum thick everywhere");
    }
}

bool near(const json& a, const json& b) {
    if (a.is_number() && b.is_number()) return near(a.get<double>(), b.get<double>());
    if (a.type() != b.type() || a.size() != b.size()) return false;
    if (a.is_object()) {
        for (auto it = a.begin(); it != a.end(); ++it)
            if (!b.contains(it.key()) || !near(it.value(), b[it.key()])) return false;
        return true;
    }
    if (a.is_array()) {
        for (size_t i = 0; i < a.size(); ++i)
            if (!near(a[i], b[i])) return false;
        return true;
    }
    return a == b;
}

bool near(const glm::dmat4& a, const glm::dmat4& b) {
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!near(a[c][r], b[c][r])) return false;
    return true;
}

}  // namespace refract::gltf
