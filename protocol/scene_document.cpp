// Parsing, validation, serialisation and merge-patch editing of the scene document.
// The field names, defaults and ranges here are the public contract; protocol/README.md and
// protocol/scene.schema.json describe the same rules and must be kept in step with this file.
#include "protocol/scene_document.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <string_view>
#include <utility>
#include <vector>

namespace refract::protocol {

const std::string& DensityVolume::emission_grid() const {
    static const std::string none;
    if (!emission.emits()) return none;
    return emission.temperature_grid.empty() ? emission.grid : emission.temperature_grid;
}

namespace {

using nlohmann::json;

std::string make_message(const std::string& pointer, const std::string& rule) {
    return (pointer.empty() ? std::string("(root)") : pointer) + ": " + rule;
}

}  // namespace

ValidationError::ValidationError(std::string pointer, std::string rule)
    : std::runtime_error(make_message(pointer, rule)), pointer_(std::move(pointer)), rule_(std::move(rule)) {}

namespace {

// RFC 6901 escaping of one reference token.
std::string escape_token(std::string_view key) {
    std::string out;
    out.reserve(key.size());
    for (char c : key) {
        if (c == '~') {
            out += "~0";
        } else if (c == '/') {
            out += "~1";
        } else {
            out += c;
        }
    }
    return out;
}

std::string child(const std::string& base, std::string_view key) {
    return base + "/" + escape_token(key);
}
std::string child(const std::string& base, std::size_t index) {
    return base + "/" + std::to_string(index);
}

// A closed or open interval with the words used to report it.
struct Range {
    double lo;
    double hi;
    bool lo_open;
    bool hi_open;
    const char* text;  // e.g. "a number in [0, 1e6]"

    bool contains(double v) const {
        if (!std::isfinite(v)) return false;
        if (lo_open ? !(v > lo) : !(v >= lo)) return false;
        if (hi_open ? !(v < hi) : !(v <= hi)) return false;
        return true;
    }
};

constexpr double kCoordMax = 1e4;

constexpr Range kCoord{-kCoordMax, kCoordMax, false, false, "a number in [-1e4, 1e4]"};
constexpr Range kFov{1.0, 170.0, true, true, "a number in (1, 170)"};
constexpr Range kExposure{-20.0, 20.0, false, false, "a number in [-20, 20]"};
constexpr Range kColor{0.0, 1e3, false, false, "a number in [0, 1e3]"};
constexpr Range kIntensity{0.0, 1e6, false, false, "a number in [0, 1e6]"};
constexpr Range kRotation{-360.0, 360.0, false, false, "a number in [-360, 360]"};
constexpr Range kCone{0.0, 90.0, true, false, "a number in (0, 90]"};
constexpr Range kScale{0.0, 1e3, true, false, "a number in (0, 1e3]"};
constexpr Range kIor{1.0, 4.0, false, false, "a number in [1, 4]"};
constexpr const char* kAbbeRule = "must be 0 (no dispersion) or a number in [5, 1000]";
constexpr Range kAbbe{0.0, 1000.0, false, false, kAbbeRule};
constexpr Range kFilmThickness{0.0, 5000.0, false, false, "a number in [0, 5000] (nm)"};
constexpr Range kCoefficient{0.0, 1e3, false, false, "a number in [0, 1000] (per metre)"};
constexpr Range kDensityScale{0.0, 1e3, false, false, "a number in [0, 1000]"};
constexpr Range kPhaseG{-0.99, 0.99, false, false, "a number in [-0.99, 0.99]"};
constexpr Range kSmoothing{0.0, 4.0, false, false, "a number in [0, 4]"};
constexpr Range kEpsilon{0.0, 1.0, true, false, "a number in (0, 1]"};
constexpr Range kMargin{0.0, kCoordMax, false, false, "a number in [0, 1e4]"};
constexpr Range kFade{0.0, kCoordMax, false, false, "a number in [0, 1e4] (metres)"};
constexpr Range kAlbedo{0.0, 1.0, false, false, "a number in [0, 1]"};
constexpr Range kChecker{0.0, kCoordMax, true, false, "a number in (0, 1e4]"};

constexpr std::size_t kMaxNameLength = 64;

}  // namespace

bool valid_name(std::string_view name) {
    if (name.empty() || name.size() > kMaxNameLength) return false;
    if (name == "." || name == "..") return false;  // never a usable file or key name
    return std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ||
               c == '.' || c == '-';
    });
}

namespace {

double length(const Vec3& v) {
    // Scaled so that tiny or large components neither underflow nor overflow.
    const double m = std::max({std::fabs(v[0]), std::fabs(v[1]), std::fabs(v[2])});
    if (m == 0.0) return 0.0;
    const double x = v[0] / m, y = v[1] / m, z = v[2] / m;
    return m * std::sqrt(x * x + y * y + z * z);
}

Vec3 normalized(const Vec3& v) {
    const double l = length(v);
    return {v[0] / l, v[1] / l, v[2] / l};
}

Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// Vectors shorter than this are treated as zero (directions) or as "the same point" (positions).
constexpr double kTiny = 1e-9;
// |sin| of the angle between two unit vectors below which they count as parallel.
constexpr double kParallel = 1e-6;

struct Blame {
    std::string pointer;
    std::string rule;
};

// Reads one document. `touched` is the JSON the caller supplied (the input of parse_scene or the
// merge patch); when a rule ties several values together, the error names the first candidate the
// caller actually wrote, so that an edit is blamed rather than the untouched value it conflicts with.
class Reader {
public:
    Reader(const Limits& limits, const json* touched) : limits_(limits), touched_(touched) {}

    SceneDocument document(const json& root) {
        SceneDocument d;
        check_object(root, "", {"camera", "image", "lights", "objects", "light", "object", "medium", "volumes",
                                "volume", "photons", "floor", "environment"},
                     "must be a JSON object");
        read_camera(root, d.camera);
        read_image(root, d.image);
        d.lights = collection<Light>(root, "lights", "light", kMaxLights, &Reader::read_light);
        d.objects = collection<Object>(root, "objects", "object", kMaxObjects, &Reader::read_object);
        check_objects_together(d.objects);
        read_medium(root, d.medium);
        d.volumes = density_volumes(root);
        read_volume(root, d.volume);
        read_photons(root, d.photons);
        read_floor(root, d.floor);
        read_environment(root, d.environment);
        return d;
    }

private:
    [[noreturn]] static void fail(const std::string& pointer, std::string rule) {
        throw ValidationError(pointer, std::move(rule));
    }

    // Whether the caller's JSON wrote the value at `pointer` (or replaced an enclosing value whole).
    bool touched(const std::string& pointer) const {
        if (touched_ == nullptr) return false;
        const json* cur = touched_;
        std::size_t pos = 0;
        while (pos < pointer.size()) {
            if (!cur->is_object()) return true;  // replaced whole (arrays, scalars, null)
            const std::size_t next = pointer.find('/', pos + 1);
            std::string token =
                pointer.substr(pos + 1, next == std::string::npos ? std::string::npos : next - pos - 1);
            std::string key;
            for (std::size_t i = 0; i < token.size(); ++i) {
                if (token[i] == '~' && i + 1 < token.size()) {
                    key += token[i + 1] == '1' ? '/' : '~';
                    ++i;
                } else {
                    key += token[i];
                }
            }
            const auto it = cur->find(key);
            if (it == cur->end()) return false;
            cur = &*it;
            pos = next == std::string::npos ? pointer.size() : next;
        }
        return true;
    }

    [[noreturn]] void fail_blaming(std::initializer_list<Blame> candidates) const {
        for (const Blame& b : candidates) {
            if (touched(b.pointer)) fail(b.pointer, b.rule);
        }
        fail(candidates.begin()->pointer, candidates.begin()->rule);
    }

    static void check_object(const json& j, const std::string& pointer,
                             std::initializer_list<std::string_view> allowed, const char* rule) {
        if (!j.is_object()) fail(pointer, rule);
        for (auto it = j.begin(); it != j.end(); ++it) {
            if (std::find(allowed.begin(), allowed.end(), std::string_view(it.key())) == allowed.end()) {
                std::string list;
                for (std::string_view a : allowed) {
                    if (!list.empty()) list += ", ";
                    list += a;
                }
                fail(child(pointer, it.key()), "unknown field (allowed here: " + list + ")");
            }
        }
    }

    // The member `key` of the object `parent` (at `base`) if present, checked to be an object with only
    // the `allowed` members; nullptr when absent.
    static const json* section(const json& parent, const std::string& base, const char* key,
                               std::initializer_list<std::string_view> allowed) {
        const auto it = parent.find(key);
        if (it == parent.end()) return nullptr;
        check_object(*it, child(base, key), allowed, "must be a JSON object");
        return &*it;
    }

    static double number_value(const json& v, const std::string& pointer, const Range& r) {
        if (!v.is_number()) fail(pointer, std::string("must be ") + r.text);
        const double x = v.get<double>();
        if (!std::isfinite(x)) fail(pointer, std::string("must be ") + r.text + " (finite)");
        if (!r.contains(x)) fail(pointer, std::string("must be ") + r.text);
        return x;
    }

    static double number(const json& obj, const std::string& base, const char* key, double dflt,
                         const Range& r) {
        const auto it = obj.find(key);
        return it == obj.end() ? dflt : number_value(*it, child(base, key), r);
    }

    // An integer in [lo, hi]; `rule` replaces the default wording where the field has more to say.
    static uint32_t uinteger(const json& obj, const std::string& base, const char* key, uint32_t dflt,
                             uint32_t lo, uint32_t hi, std::string rule = {}) {
        const auto it = obj.find(key);
        if (it == obj.end()) return dflt;
        const std::string pointer = child(base, key);
        if (rule.empty())
            rule = "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
        const json& v = *it;
        if (v.is_number_unsigned()) {
            const auto x = v.get<uint64_t>();
            if (x < lo || x > hi) fail(pointer, rule);
            return static_cast<uint32_t>(x);
        }
        if (v.is_number_integer()) {
            const auto x = v.get<int64_t>();
            if (x < 0 || static_cast<uint64_t>(x) < lo || static_cast<uint64_t>(x) > hi) fail(pointer, rule);
            return static_cast<uint32_t>(x);
        }
        if (v.is_number_float()) {
            // A float with no fractional part is an integer, as in JSON Schema.
            const double x = v.get<double>();
            if (!std::isfinite(x) || std::floor(x) != x || x < static_cast<double>(lo) ||
                x > static_cast<double>(hi)) {
                fail(pointer, rule);
            }
            return static_cast<uint32_t>(x);
        }
        fail(pointer, rule);
    }

    static bool boolean(const json& obj, const std::string& base, const char* key, bool dflt) {
        const auto it = obj.find(key);
        if (it == obj.end()) return dflt;
        if (!it->is_boolean()) fail(child(base, key), "must be true or false");
        return it->get<bool>();
    }

    static Vec3 vec3(const json& obj, const std::string& base, const char* key, const Vec3& dflt,
                     const Range& r) {
        const auto it = obj.find(key);
        if (it == obj.end()) return dflt;
        const std::string pointer = child(base, key);
        if (!it->is_array() || it->size() != 3) {
            fail(pointer, std::string("must be an array of 3 numbers, each ") + r.text);
        }
        Vec3 out{};
        for (std::size_t i = 0; i < 3; ++i) out[i] = number_value((*it)[i], child(pointer, i), r);
        return out;
    }

    template <class E>
    static E enumeration(const json& obj, const std::string& base, const char* key, E dflt,
                         std::initializer_list<std::pair<std::string_view, E>> names) {
        const auto it = obj.find(key);
        if (it == obj.end()) return dflt;
        if (it->is_string()) {
            const auto& s = it->get_ref<const std::string&>();
            for (const auto& [name, value] : names) {
                if (s == name) return value;
            }
        }
        std::string rule = "must be one of";
        bool first = true;
        for (const auto& entry : names) {
            rule += first ? " \"" : ", \"";
            rule += entry.first;
            rule += '"';
            first = false;
        }
        fail(child(base, key), rule);
    }

    static const std::string* string_member(const json& obj, const std::string& base, const char* key,
                                            const char* rule) {
        const auto it = obj.find(key);
        if (it == obj.end()) return nullptr;
        if (!it->is_string()) fail(child(base, key), rule);
        return &it->get_ref<const std::string&>();
    }

    static Phase phase(const json& parent, const std::string& base, Phase p) {
        const json* j = section(parent, base, "phase", {"model", "g"});
        if (j == nullptr) return p;
        const std::string pointer = child(base, "phase");
        p.model = enumeration(*j, pointer, "model", p.model,
                              {{"isotropic", PhaseModel::isotropic},
                               {"schlick", PhaseModel::schlick},
                               {"henyey-greenstein", PhaseModel::henyey_greenstein}});
        p.g = number(*j, pointer, "g", p.g, kPhaseG);
        return p;
    }

    // Extinction and scattering of a participating medium: scattering may not exceed extinction.
    void coefficients(const json& obj, const std::string& base, Vec3& extinction, Vec3& scattering) const {
        extinction = vec3(obj, base, "extinction", extinction, kCoefficient);
        scattering = vec3(obj, base, "scattering", scattering, kCoefficient);
        check_coefficients(base, extinction, scattering);
    }

    void check_coefficients(const std::string& base, const Vec3& extinction, const Vec3& scattering) const {
        for (std::size_t i = 0; i < 3; ++i) {
            if (scattering[i] > extinction[i]) {
                const std::string c = std::to_string(i);
                fail_blaming({{child(child(base, "scattering"), i),
                               "must be <= extinction[" + c + "] (scattering cannot exceed extinction)"},
                              {child(child(base, "extinction"), i),
                               "must be >= scattering[" + c + "] (scattering cannot exceed extinction)"}});
            }
        }
    }

    void read_camera(const json& root, Camera& c) const {
        const std::string base = "/camera";
        if (const json* j = section(root, "", "camera", {"position", "target", "up", "fov_deg"})) {
            c.position = vec3(*j, base, "position", c.position, kCoord);
            c.target = vec3(*j, base, "target", c.target, kCoord);
            c.up = vec3(*j, base, "up", c.up, kCoord);
            c.fov_deg = number(*j, base, "fov_deg", c.fov_deg, kFov);
        }
        const Vec3 view{c.target[0] - c.position[0], c.target[1] - c.position[1],
                        c.target[2] - c.position[2]};
        if (length(view) < kTiny) {
            fail_blaming(
                {{"/camera/target", "must differ from /camera/position (the camera needs a view direction)"},
                 {"/camera/position",
                  "must differ from /camera/target (the camera needs a view direction)"}});
        }
        if (length(c.up) < kTiny) fail("/camera/up", "must be a non-zero vector");
        if (length(cross(normalized(view), normalized(c.up))) < kParallel) {
            fail_blaming(
                {{"/camera/up", "must not be parallel to the view direction (target - position)"},
                 {"/camera/target", "view direction (target - position) must not be parallel to /camera/up"},
                 {"/camera/position",
                  "view direction (target - position) must not be parallel to /camera/up"}});
        }
    }

    void read_image(const json& root, Image& im) const {
        const std::string base = "/image";
        const json* j = section(root, "", "image", {"width", "height", "exposure"});
        if (j == nullptr) return;
        im.width = uinteger(*j, base, "width", im.width, 1, limits_.max_image_side);
        im.height = uinteger(*j, base, "height", im.height, 1, limits_.max_image_side);
        im.exposure = number(*j, base, "exposure", im.exposure, kExposure);
    }

    // A collection (`plural`: {NAME: member}) or, in the older form, its one member (`singular`), which
    // is then named `singular`. Absent: the default collection of one.
    template <class T>
    std::map<std::string, T> collection(const json& root, const char* plural, const char* singular, size_t most,
                                        void (Reader::*read)(const json&, const std::string&, T&) const) const {
        const auto one = root.find(singular);
        const auto many = root.find(plural);
        if (one != root.end() && many != root.end())
            fail(child("", singular), std::string("give either /") + singular + " (one) or /" + plural + ", not both");
        if (many == root.end()) {
            T member{};
            (this->*read)(one == root.end() ? json::object() : *one, child("", singular), member);
            return {{singular, std::move(member)}};
        }
        const std::string base = child("", plural);
        if (!many->is_object()) fail(base, "must be a JSON object of named members");
        const std::string count_rule = "must hold 1 to " + std::to_string(most) + " members";
        if (many->empty() || many->size() > most) fail(base, count_rule);
        std::map<std::string, T> members;
        for (const auto& [name, value] : many->items()) {
            const std::string pointer = child(base, name);
            if (!valid_name(name)) fail(pointer, "a name must be 1 to 64 characters of [A-Za-z0-9_.-]");
            T member{};
            (this->*read)(value, pointer, member);
            members.emplace(name, std::move(member));
        }
        return members;
    }

    void read_light(const json& light, const std::string& base, Light& l) const {
        check_object(light, base, {"type", "position", "direction", "color", "intensity", "cone_deg"},
                     "must be a JSON object");
        l.type = enumeration(light, base, "type", l.type,
                             {{"point", LightType::point},
                              {"spot", LightType::spot},
                              {"directional", LightType::directional}});
        l.position = vec3(light, base, "position", l.position, kCoord);
        l.direction = vec3(light, base, "direction", l.direction, kCoord);
        l.color = vec3(light, base, "color", l.color, kColor);
        l.intensity = number(light, base, "intensity", l.intensity, kIntensity);
        l.cone_deg = number(light, base, "cone_deg", l.cone_deg, kCone);
        if (l.type != LightType::point && length(l.direction) < kTiny) {
            fail_blaming({{child(base, "direction"), "must be a non-zero vector for spot and directional lights"},
                          {child(base, "type"), "a spot or directional light needs a non-zero " + child(base, "direction")}});
        }
    }

    void read_object(const json& object, const std::string& base, Object& o) const {
        check_object(object, base,
                     {"mesh", "position", "rotation_deg", "scale", "resolution", "index_field", "ior", "maxwell_n0",
                      "abbe", "fresnel", "film", "extinction", "scattering", "phase", "grid"},
                     "must be a JSON object");
        static constexpr const char* kMeshRule =
            "must be \"sphere\", \"cube\", \"torus\", \"prism\", \"bunny\" or \"upload:NAME\" with NAME 1..64 characters of "
            "[A-Za-z0-9_.-]";
        if (const std::string* mesh = string_member(object, base, "mesh", kMeshRule)) {
            constexpr std::string_view upload = "upload:";
            const bool builtin = *mesh == "sphere" || *mesh == "cube" || *mesh == "torus" || *mesh == "prism" ||
                                 *mesh == "bunny";
            const bool uploaded = mesh->compare(0, upload.size(), upload) == 0 &&
                                  valid_name(std::string_view(*mesh).substr(upload.size()));
            if (!builtin && !uploaded) fail(child(base, "mesh"), kMeshRule);
            o.mesh = *mesh;
        }
        o.position = vec3(object, base, "position", o.position, kCoord);
        o.rotation_deg = vec3(object, base, "rotation_deg", o.rotation_deg, kCoord);
        o.scale = number(object, base, "scale", o.scale, kScale);
        // 0 takes the scene's voxel; fewer than 16 voxels across would not resolve the object at all.
        const std::string resolution_rule = "must be 0 (the scene's voxel) or an integer in [" +
                                            std::to_string(kMinObjectResolution) + ", " +
                                            std::to_string(limits_.max_resolution) + "]";
        o.resolution =
            uinteger(object, base, "resolution", o.resolution, 0, limits_.max_resolution, resolution_rule);
        if (o.resolution != 0 && o.resolution < kMinObjectResolution)
            fail(child(base, "resolution"), resolution_rule);
        o.index_field = enumeration(object, base, "index_field", o.index_field,
                                    {{"uniform", IndexFieldKind::uniform},
                                     {"luneburg", IndexFieldKind::luneburg},
                                     {"maxwell", IndexFieldKind::maxwell},
                                     {"grid", IndexFieldKind::grid}});
        o.ior = number(object, base, "ior", o.ior, kIor);
        o.maxwell_n0 = number(object, base, "maxwell_n0", o.maxwell_n0, kIor);
        o.abbe = number(object, base, "abbe", o.abbe, kAbbe);
        // Below 5 no glass exists, and channels would part by more than the field's own contrast.
        if (o.abbe > 0.0 && o.abbe < 5.0) fail(child(base, "abbe"), kAbbeRule);
        o.fresnel = boolean(object, base, "fresnel", o.fresnel);
        if (const json* f = section(object, base, "film", {"ior", "top_nm", "bottom_nm"})) {
            const std::string film = base + "/film";
            o.film.ior = number(*f, film, "ior", o.film.ior, kIor);
            o.film.top_nm = number(*f, film, "top_nm", o.film.top_nm, kFilmThickness);
            o.film.bottom_nm = number(*f, film, "bottom_nm", o.film.bottom_nm, kFilmThickness);
        }
        coefficients(object, base, o.extinction, o.scattering);
        o.phase = phase(object, base, o.phase);
        static constexpr const char* kGridRule =
            "must be \"\" or a name of 1..64 characters of [A-Za-z0-9_.-]";
        if (const std::string* grid = string_member(object, base, "grid", kGridRule)) {
            if (!grid->empty() && !valid_name(*grid)) fail(child(base, "grid"), kGridRule);
            o.grid = *grid;
        }
        if (o.index_field == IndexFieldKind::grid && o.grid.empty()) {
            fail_blaming({{child(base, "grid"), "must name a stored grid when " + child(base, "index_field") + " is \"grid\""},
                          {child(base, "index_field"), "\"grid\" requires a non-empty " + child(base, "grid")}});
        }
    }

    // What several objects must share: an imported grid is the scene's whole field, so it stands alone;
    // and the channels' index contrast is scaled by one Abbe number per scene (dispersion_scales).
    void check_objects_together(const std::map<std::string, Object>& objects) const {
        if (objects.size() < 2) return;
        const auto& [first_name, first] = *objects.begin();
        const std::string first_abbe = child(child("/objects", first_name), "abbe");
        for (const auto& [name, o] : objects) {
            const std::string base = child("/objects", name);
            if (o.index_field == IndexFieldKind::grid)
                fail(child(base, "index_field"), "\"grid\" fills the scene's whole volume: it must be the only object");
            if (o.abbe != first.abbe)
                fail_blaming({{child(base, "abbe"), "every object takes the same Abbe number (dispersion is one per scene): " +
                                                        first_abbe + " is " + std::to_string(first.abbe)},
                              {first_abbe, "every object takes the same Abbe number (dispersion is one per scene): " +
                                               child(base, "abbe") + " is " + std::to_string(o.abbe)}});
        }
    }

    void read_medium(const json& root, Medium& m) const {
        const std::string base = "/medium";
        const json* j = section(root, "", "medium", {"ior", "extinction", "scattering", "phase", "fade"});
        if (j == nullptr) return;
        m.ior = number(*j, base, "ior", m.ior, kIor);
        coefficients(*j, base, m.extinction, m.scattering);
        m.phase = phase(*j, base, m.phase);
        m.fade = number(*j, base, "fade", m.fade, kFade);
    }

    // /volumes: 0 to kMaxVolumes named members (absent or null: none).
    std::map<std::string, DensityVolume> density_volumes(const json& root) const {
        const auto many = root.find("volumes");
        if (many == root.end() || many->is_null()) return {};
        const std::string base = "/volumes";
        if (!many->is_object()) fail(base, "must be a JSON object of named members");
        if (many->size() > kMaxVolumes)
            fail(base, "must hold at most " + std::to_string(kMaxVolumes) + " members");
        std::map<std::string, DensityVolume> members;
        for (const auto& [name, value] : many->items()) {
            const std::string pointer = child(base, name);
            if (!valid_name(name)) fail(pointer, "a name must be 1 to 64 characters of [A-Za-z0-9_.-]");
            DensityVolume member{};
            read_density_volume(value, pointer, member);
            members.emplace(name, std::move(member));
        }
        return members;
    }

    void read_density_volume(const json& volume, const std::string& base, DensityVolume& v) const {
        check_object(volume, base,
                     {"asset", "grid", "position", "rotation_deg", "scale", "density_scale", "extinction",
                      "scattering", "phase", "emission"},
                     "must be a JSON object");
        static constexpr const char* kAssetRule =
            "must name an uploaded volume: 1..64 characters of [A-Za-z0-9_.-]";
        const std::string* asset = string_member(volume, base, "asset", kAssetRule);
        if (asset == nullptr || !valid_name(*asset)) fail(child(base, "asset"), kAssetRule);
        v.asset = *asset;
        static constexpr const char* kGridRule = "must name a float grid of the volume: 1..64 characters";
        if (const std::string* grid = string_member(volume, base, "grid", kGridRule)) {
            if (grid->empty() || grid->size() > kMaxNameLength) fail(child(base, "grid"), kGridRule);
            v.grid = *grid;
        }
        v.position = vec3(volume, base, "position", v.position, kCoord);
        v.rotation_deg = vec3(volume, base, "rotation_deg", v.rotation_deg, kCoord);
        v.scale = number(volume, base, "scale", v.scale, kScale);
        v.density_scale = number(volume, base, "density_scale", v.density_scale, kDensityScale);
        coefficients(volume, base, v.extinction, v.scattering);
        v.phase = phase(volume, base, v.phase);
        // The medium field keeps one g per voxel (the volumes' scattering-weighted mean), which Schlick's
        // k would not mix with.
        if (v.phase.model == PhaseModel::schlick)
            fail(child(child(base, "phase"), "model"), "must be \"isotropic\" or \"henyey-greenstein\" for a volume");
        read_volume_emission(volume, base, v.emission);
    }

    void read_volume_emission(const json& volume, const std::string& base, VolumeEmission& e) const {
        const json* j = section(volume, base, "emission", {"grid", "temperature_grid", "color", "intensity"});
        if (j == nullptr) return;
        const std::string pointer = child(base, "emission");
        static constexpr const char* kGridRule = "must be \"\" or name a float grid of the volume: 1..64 characters";
        for (auto [key, target] : {std::pair{"grid", &e.grid}, std::pair{"temperature_grid", &e.temperature_grid}})
            if (const std::string* grid = string_member(*j, pointer, key, kGridRule)) {
                if (grid->size() > kMaxNameLength) fail(child(pointer, key), kGridRule);
                *target = *grid;
            }
        e.color = vec3(*j, pointer, "color", e.color, kColor);
        e.intensity = number(*j, pointer, "intensity", e.intensity, kIntensity);
        if (!e.emits()) return;
        if (e.grid.empty() && e.temperature_grid.empty())
            fail_blaming({{child(pointer, "grid"), "must name the grid that emits when intensity is above 0 (or "
                                                   "name a temperature_grid)"},
                          {child(pointer, "intensity"), "above 0 requires a grid or a temperature_grid"}});
        if (!e.grid.empty() && !e.temperature_grid.empty())
            fail_blaming({{child(pointer, "grid"), "must be \"\" when a temperature_grid is named (one or the other)"},
                          {child(pointer, "temperature_grid"), "must be \"\" when a grid is named (one or the other)"}});
    }

    void read_volume(const json& root, Volume& v) const {
        const std::string base = "/volume";
        const json* j =
            section(root, "", "volume", {"resolution", "smoothing", "octree_epsilon", "bounds", "margin"});
        if (j == nullptr) return;
        v.resolution = uinteger(*j, base, "resolution", v.resolution, kMinVolumeResolution, limits_.max_resolution);
        v.smoothing = number(*j, base, "smoothing", v.smoothing, kSmoothing);
        v.octree_epsilon = number(*j, base, "octree_epsilon", v.octree_epsilon, kEpsilon);
        const auto bit = j->find("bounds");
        if (bit != j->end() && !bit->is_null()) {  // null: no bounds, as a merge patch would leave it
            const std::string pointer = child(base, "bounds");
            check_object(*bit, pointer, {"min", "max"}, "must be a JSON object {min, max} or null");
            Bounds b;
            b.min = vec3(*bit, pointer, "min", b.min, kCoord);
            b.max = vec3(*bit, pointer, "max", b.max, kCoord);
            for (std::size_t i = 0; i < 3; ++i) {
                if (!(b.min[i] < b.max[i])) {
                    const std::string c = std::to_string(i);
                    fail_blaming({{child(child(pointer, "max"), i), "must be greater than min[" + c + "]"},
                                  {child(child(pointer, "min"), i), "must be less than max[" + c + "]"}});
                }
            }
            v.bounds = b;
        }
        v.margin = number(*j, base, "margin", v.margin, kMargin);
    }

    void read_photons(const json& root, Photons& p) const {
        const std::string base = "/photons";
        const json* j = section(root, "", "photons", {"count", "seed", "max_bounces"});
        if (j == nullptr) return;
        p.count = uinteger(*j, base, "count", p.count, 1, limits_.max_photons);
        p.seed = uinteger(*j, base, "seed", p.seed, 0, std::numeric_limits<uint32_t>::max());
        p.max_bounces = uinteger(*j, base, "max_bounces", p.max_bounces, 0, kMaxBounces);
    }

    static void read_floor(const json& root, Floor& f) {
        const std::string base = "/floor";
        const json* j =
            section(root, "", "floor", {"enabled", "height", "albedo", "checker", "checker_size"});
        if (j == nullptr) return;
        f.enabled = boolean(*j, base, "enabled", f.enabled);
        f.height = number(*j, base, "height", f.height, kCoord);
        f.albedo = vec3(*j, base, "albedo", f.albedo, kAlbedo);
        f.checker = boolean(*j, base, "checker", f.checker);
        f.checker_size = number(*j, base, "checker_size", f.checker_size, kChecker);
    }

    void read_environment(const json& root, Environment& e) const {
        const std::string base = "/environment";
        const json* j =
            section(root, "", "environment", {"type", "color", "intensity", "image", "rotation_deg", "lights"});
        if (j == nullptr) return;
        e.type = enumeration(*j, base, "type", e.type,
                             {{"sky", EnvironmentKind::sky}, {"uniform", EnvironmentKind::uniform},
                              {"image", EnvironmentKind::image}});
        e.color = vec3(*j, base, "color", e.color, kColor);
        e.intensity = number(*j, base, "intensity", e.intensity, kIntensity);
        static constexpr const char* kImageRule = "must be \"\" or a name of 1..64 characters of [A-Za-z0-9_.-]";
        if (const std::string* image = string_member(*j, base, "image", kImageRule)) {
            if (!image->empty() && !valid_name(*image)) fail(child(base, "image"), kImageRule);
            e.image = *image;
        }
        e.rotation_deg = number(*j, base, "rotation_deg", e.rotation_deg, kRotation);
        e.lights = boolean(*j, base, "lights", e.lights);
        if (e.type == EnvironmentKind::image && e.image.empty()) {
            fail_blaming({{"/environment/image", "must name an environment when /environment/type is \"image\""},
                          {"/environment/type", "\"image\" requires a non-empty /environment/image"}});
        }
    }

    const Limits& limits_;
    const json* touched_;
};

json vec(const Vec3& v) {
    return json::array({v[0], v[1], v[2]});
}

const char* name(LightType t) {
    switch (t) {
        case LightType::point:
            return "point";
        case LightType::spot:
            return "spot";
        case LightType::directional:
            return "directional";
    }
    return "spot";
}

const char* name(PhaseModel m) {
    switch (m) {
        case PhaseModel::isotropic:
            return "isotropic";
        case PhaseModel::schlick:
            return "schlick";
        case PhaseModel::henyey_greenstein:
            return "henyey-greenstein";
    }
    return "isotropic";
}

const char* name(IndexFieldKind k) {
    switch (k) {
        case IndexFieldKind::uniform:
            return "uniform";
        case IndexFieldKind::luneburg:
            return "luneburg";
        case IndexFieldKind::maxwell:
            return "maxwell";
        case IndexFieldKind::grid:
            return "grid";
    }
    return "uniform";
}

const char* name(EnvironmentKind k) {
    switch (k) {
        case EnvironmentKind::sky:
            return "sky";
        case EnvironmentKind::uniform:
            return "uniform";
        case EnvironmentKind::image:
            return "image";
    }
    return "sky";
}

json phase_json(const Phase& p) {
    return {{"model", name(p.model)}, {"g", p.g}};
}

json light_json(const Light& l) {
    return {{"type", name(l.type)},     {"position", vec(l.position)}, {"direction", vec(l.direction)},
            {"color", vec(l.color)},    {"intensity", l.intensity},     {"cone_deg", l.cone_deg}};
}

json object_json(const Object& o) {
    return {{"mesh", o.mesh},
            {"position", vec(o.position)},
            {"rotation_deg", vec(o.rotation_deg)},
            {"scale", o.scale},
            {"resolution", o.resolution},
            {"index_field", name(o.index_field)},
            {"ior", o.ior},
            {"maxwell_n0", o.maxwell_n0},
            {"abbe", o.abbe},
            {"fresnel", o.fresnel},
            {"film", {{"ior", o.film.ior}, {"top_nm", o.film.top_nm}, {"bottom_nm", o.film.bottom_nm}}},
            {"extinction", vec(o.extinction)},
            {"scattering", vec(o.scattering)},
            {"phase", phase_json(o.phase)},
            {"grid", o.grid}};
}

json density_volume_json(const DensityVolume& v) {
    return {{"asset", v.asset},
            {"grid", v.grid},
            {"position", vec(v.position)},
            {"rotation_deg", vec(v.rotation_deg)},
            {"scale", v.scale},
            {"density_scale", v.density_scale},
            {"extinction", vec(v.extinction)},
            {"scattering", vec(v.scattering)},
            {"phase", phase_json(v.phase)},
            {"emission",
             {{"grid", v.emission.grid},
              {"temperature_grid", v.emission.temperature_grid},
              {"color", vec(v.emission.color)},
              {"intensity", v.emission.intensity}}}};
}

// A patch in the older form edits the one member of a collection through its singular name: rewritten
// here to the collection's form, `renamed` maps the member's pointer back to the name the patch used.
struct OlderForm {
    json patch;
    std::vector<std::pair<std::string, std::string>> renamed;  // {"/lights/NAME", "/light"}
    std::vector<std::string> replaced;  // collections the patch replaces whole (removed before it applies)
};

template <class T>
void rewrite_member(OlderForm& form, const char* singular, const char* plural, const std::map<std::string, T>& members,
                    const json& defaults) {
    const auto one = form.patch.find(singular);
    if (one == form.patch.end()) return;
    const std::string pointer = child("", singular);
    const auto many = form.patch.find(plural);
    if (many != form.patch.end() && many->is_null()) {
        // Removing the collection and giving the one member replaces the collection by a collection of
        // that member, named as a document in the older form names it (a whole document in that form,
        // put over one in this form, is such a patch).
        json member = *one;
        form.patch.erase(one);
        form.patch[plural] = {{singular, member.is_null() ? defaults : std::move(member)}};
        form.replaced.emplace_back(plural);
        form.renamed.emplace_back(child(child("", plural), singular), pointer);
        return;
    }
    if (many != form.patch.end())
        throw ValidationError(pointer, std::string("give either /") + singular + " (one) or /" + plural + ", not both");
    if (members.size() != 1)
        throw ValidationError(pointer, "the scene has " + std::to_string(members.size()) + " " + plural +
                                           ": edit one as /" + plural + "/NAME");
    const std::string& key = members.begin()->first;
    // null reset the section to its defaults in the older form; in a collection it would remove the member.
    json member = one->is_null() ? defaults : *one;
    form.patch.erase(one);
    form.patch[plural] = {{key, std::move(member)}};
    form.renamed.emplace_back(child(child("", plural), key), pointer);
}

}  // namespace

SceneDocument parse_scene(const json& j, const Limits& limits) {
    return Reader(limits, &j).document(j);
}

View parse_view(const json& j, const Limits& limits, const std::string& base) {
    if (!j.is_object()) throw ValidationError(base, "must be an object {\"width\", \"height\", \"camera\"} or null");
    for (const auto& [key, value] : j.items()) {
        if (key != "width" && key != "height" && key != "camera")
            throw ValidationError(child(base, key), "is not a member of a view (width, height, camera)");
    }
    for (const char* side : {"width", "height"}) {
        if (!j.contains(side)) throw ValidationError(child(base, side), "is required: the view's image size in pixels");
    }
    // The document's own rules, on a document that holds only this image size and camera.
    json document = {{"image", {{"width", j["width"]}, {"height", j["height"]}}}};
    const bool own_camera = j.contains("camera") && !j["camera"].is_null();
    if (own_camera) document["camera"] = j["camera"];
    SceneDocument checked;
    try {
        checked = Reader(limits, &document).document(document);
    } catch (const ValidationError& e) {
        // "/image/width" is the view's "/width"; "/camera/..." its own "/camera/...".
        const std::string& pointer = e.pointer();
        const std::string image = "/image";
        std::string moved = pointer.compare(0, image.size(), image) == 0 ? base + pointer.substr(image.size()) : base + pointer;
        std::string rule = e.rule();
        for (size_t at = rule.find("/camera/"); at != std::string::npos; at = rule.find("/camera/", at + base.size() + 1))
            rule.insert(at, base);
        throw ValidationError(std::move(moved), std::move(rule));
    }
    View view{checked.image.width, checked.image.height, std::nullopt};
    if (own_camera) view.camera = checked.camera;
    return view;
}

SceneDocument seen_through(SceneDocument document, const View& view) {
    if (view.width != 0 && view.height != 0) {
        document.image.width = view.width;
        document.image.height = view.height;
    }
    if (view.camera) document.camera = *view.camera;
    return document;
}

json to_json(const SceneDocument& d) {
    json volume = {{"resolution", d.volume.resolution},
                   {"smoothing", d.volume.smoothing},
                   {"octree_epsilon", d.volume.octree_epsilon},
                   {"margin", d.volume.margin}};
    if (d.volume.bounds)
        volume["bounds"] = {{"min", vec(d.volume.bounds->min)}, {"max", vec(d.volume.bounds->max)}};
    json lights = json::object(), objects = json::object(), volumes = json::object();
    for (const auto& [key, light] : d.lights) lights[key] = light_json(light);
    for (const auto& [key, object] : d.objects) objects[key] = object_json(object);
    for (const auto& [key, density] : d.volumes) volumes[key] = density_volume_json(density);
    return {
        {"camera",
         {{"position", vec(d.camera.position)},
          {"target", vec(d.camera.target)},
          {"up", vec(d.camera.up)},
          {"fov_deg", d.camera.fov_deg}}},
        {"image", {{"width", d.image.width}, {"height", d.image.height}, {"exposure", d.image.exposure}}},
        {"lights", std::move(lights)},
        {"objects", std::move(objects)},
        {"medium",
         {{"ior", d.medium.ior},
          {"extinction", vec(d.medium.extinction)},
          {"scattering", vec(d.medium.scattering)},
          {"phase", phase_json(d.medium.phase)},
          {"fade", d.medium.fade}}},
        {"volumes", std::move(volumes)},
        {"volume", std::move(volume)},
        {"photons", {{"count", d.photons.count}, {"seed", d.photons.seed}, {"max_bounces", d.photons.max_bounces}}},
        {"floor",
         {{"enabled", d.floor.enabled},
          {"height", d.floor.height},
          {"albedo", vec(d.floor.albedo)},
          {"checker", d.floor.checker},
          {"checker_size", d.floor.checker_size}}},
        {"environment",
         {{"type", name(d.environment.type)},
          {"color", vec(d.environment.color)},
          {"intensity", d.environment.intensity},
          {"image", d.environment.image},
          {"rotation_deg", d.environment.rotation_deg},
          {"lights", d.environment.lights}}},
    };
}

SceneDocument apply_merge_patch(const SceneDocument& current, const json& patch, const Limits& limits) {
    OlderForm form{patch, {}};
    if (patch.is_object()) {
        rewrite_member(form, "light", "lights", current.lights, light_json(Light{}));
        rewrite_member(form, "object", "objects", current.objects, object_json(Object{}));
    }
    json merged = to_json(current);
    for (const std::string& collection : form.replaced) merged.erase(collection);
    merged.merge_patch(form.patch);  // RFC 7396: objects merge recursively, null deletes, anything else replaces
    try {
        return Reader(limits, &form.patch).document(merged);
    } catch (const ValidationError& e) {
        for (const auto& [member, older] : form.renamed) {
            const std::string& p = e.pointer();
            if (p.compare(0, member.size(), member) == 0 && (p.size() == member.size() || p[member.size()] == '/')) {
                std::string rule = e.rule();  // it may name a sibling by its pointer
                for (size_t at = rule.find(member); at != std::string::npos; at = rule.find(member, at))
                    rule.replace(at, member.size(), older);
                throw ValidationError(older + p.substr(member.size()), rule);
            }
        }
        throw;
    }
}

}  // namespace refract::protocol
