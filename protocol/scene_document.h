// The scene document: the one public description of a Refract scene (see protocol/README.md).
// Parsed and validated only here; the CLI, the daemon and the tests all go through this header.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

namespace refract::protocol {

using Vec3 = std::array<double, 3>;

enum class LightType { point, spot, directional };
enum class PhaseModel { isotropic, schlick, henyey_greenstein };
enum class IndexFieldKind { uniform, luneburg, maxwell, grid };
enum class EnvironmentKind { sky, uniform, image };

struct Phase {
    PhaseModel model = PhaseModel::isotropic;
    double g = 0.0;  // Henyey-Greenstein g or Schlick k, in (-1, 1); > 0 favours forward scattering

    bool operator==(const Phase&) const = default;
};

struct Camera {
    Vec3 position{0.0, 0.5, 5.0};
    Vec3 target{0.0, -0.35, 0.0};
    Vec3 up{0.0, 1.0, 0.0};
    double fov_deg = 35.0;  // vertical

    bool operator==(const Camera&) const = default;
};

struct Image {
    uint32_t width = 512;
    uint32_t height = 512;
    double exposure = 0.5;  // stops: linear radiance is scaled by 2^exposure before tone mapping

    bool operator==(const Image&) const = default;
};

struct Light {
    LightType type = LightType::spot;
    Vec3 position{2.0, 3.0, 1.0};
    Vec3 direction{-2.0, -3.0, -1.0};  // spot axis or directional travel direction (normalized on use)
    Vec3 color{1.0, 1.0, 1.0};         // linear RGB, multiplies intensity
    double intensity = 20.0;           // W/sr for point and spot, W/m^2 for directional
    double cone_deg = 25.0;            // spot half-angle

    bool operator==(const Light&) const = default;
};

// A thin film on the object's boundary (soap, an anti-reflection coating): its thickness varies linearly
// with height from top_nm at the object's top (position.y + scale) to bottom_nm at its bottom
// (position.y - scale), as a draining soap film does; 0 at both is no film.
struct Film {
    double ior = 1.33;
    double top_nm = 0.0;
    double bottom_nm = 0.0;

    bool operator==(const Film&) const = default;
};

struct Object {
    std::string mesh = "sphere";  // "sphere" | "cube" | "torus" | "prism" | "bunny" | "upload:NAME"
    Vec3 position{0.0, 0.0, 0.0};
    Vec3 rotation_deg{0.0, 0.0, 0.0};  // XYZ Euler angles, applied X then Y then Z
    double scale = 1.0;
    uint32_t resolution = 0;  // voxels along its own bounds' longest side; 0: the scene's voxel
    IndexFieldKind index_field = IndexFieldKind::uniform;
    double ior = 1.5;        // for uniform; luneburg ignores it; maxwell uses it as n0 when set via maxwell_n0
    double maxwell_n0 = 2.0; // n0 of the Maxwell fish-eye
    // Abbe number V_d of the index contrast against the medium: each colour channel's index departs
    // from the medium's by (1 + k_c / V) times the field's (Cauchy's law; passes::dispersion_scales).
    // 0: no dispersion.
    double abbe = 0.0;
    // The boundary reflects by the Fresnel equations (photons and eye rays); false: it only refracts.
    bool fresnel = true;
    Film film;
    Vec3 extinction{0.05, 0.05, 0.05};  // per metre
    Vec3 scattering{0.02, 0.02, 0.02};  // per metre, each channel <= extinction
    Phase phase{};
    // Set only for index_field == grid (PUT /api/scenes/{id}/index-field): the name of the stored grid.
    std::string grid;

    bool operator==(const Object&) const = default;
};

struct Medium {
    double ior = 1.0;
    Vec3 extinction{0.2, 0.2, 0.2};
    Vec3 scattering{0.2, 0.2, 0.2};
    Phase phase{PhaseModel::henyey_greenstein, 0.3};
    // Metres over which the medium's density falls smoothly to 0 at the grid's faces, so that the fog's
    // box shows no edge; 0: homogeneous up to the faces.
    double fade = 0.3;

    bool operator==(const Medium&) const = default;
};

struct Bounds {
    Vec3 min{-1.0, -1.0, -1.0};
    Vec3 max{1.0, 1.0, 1.0};

    bool operator==(const Bounds&) const = default;
};

struct Volume {
    uint32_t resolution = 128;  // voxels along the longest axis, 32..512
    double smoothing = 0.75;    // Gaussian sigma in voxels
    double octree_epsilon = 0.005;
    std::optional<Bounds> bounds;  // world box the grid covers; absent: object bounds grown by margin
    double margin = 0.35;          // metres added on every side when bounds is absent

    bool operator==(const Volume&) const = default;
};

// Most scattering events per photon (Photons::max_bounces).
inline constexpr uint32_t kMaxBounces = 1024;

struct Photons {
    uint32_t count = 1u << 18;
    uint32_t seed = 1;
    // Scattering events a photon's random walk may take (0: photons are only attenuated, and the viewing
    // pass adds the one scattering event, as in Sun et al. 2008).
    uint32_t max_bounces = 0;

    bool operator==(const Photons&) const = default;
};

struct Floor {
    bool enabled = true;
    double height = -1.0;
    Vec3 albedo{0.8, 0.8, 0.8};
    bool checker = true;
    double checker_size = 0.25;  // metres

    bool operator==(const Floor&) const = default;
};

// What rays that leave the scene see (the backdrop, and what reflections and refractions show). A
// uniform or image environment also lights the scene (photons from it, and its irradiance on the floor);
// the built-in sky is a backdrop only, so scenes without an environment look as they always did.
struct Environment {
    EnvironmentKind type = EnvironmentKind::sky;  // the built-in dark sky gradient, one colour, or an image
    Vec3 color{1.0, 1.0, 1.0};                    // linear RGB radiance of a uniform environment (W/(m^2 sr))
    double intensity = 1.0;                       // multiplies any of them
    // The equirectangular environment named (uploaded with PUT /api/environments/NAME, or built in) for
    // type image; "" otherwise.
    std::string image;
    double rotation_deg = 0.0;  // turns the image about the vertical axis (+y), counter-clockwise from above
    // A uniform or image environment lights the scene (photons, the floor's irradiance); false: it is a
    // backdrop only, like the sky (a studio backdrop behind a dark stage; not physical).
    bool lights = true;

    bool operator==(const Environment&) const = default;
};

// A heterogeneous medium (smoke, a cloud) from an uploaded OpenVDB volume: one float grid of it, placed
// in the scene, whose value times density_scale is the density; extinction and scattering are per unit
// density (per metre at density 1). Where it overlaps the homogeneous medium or another volume, the
// coefficients add. Emission (issue 39, point 4) is not read yet.
// Light a volume gives off along every direction alike: emitted radiance per metre of path, `intensity`
// times either `color` times the value of the float `grid` or, from a grid in kelvin
// (`temperature_grid`), the blackbody's colour and brightness relative to one at 1500 K. Intensity 0
// (the default) emits nothing; above 0 exactly one of the two grids is named.
struct VolumeEmission {
    std::string grid;              // a float grid of the volume's file ("" for none)
    std::string temperature_grid;  // a float grid in kelvin ("" for none)
    Vec3 color{1.0, 1.0, 1.0};     // with `grid`
    double intensity = 0.0;

    bool emits() const { return intensity > 0.0; }
    bool operator==(const VolumeEmission&) const = default;
};

struct DensityVolume {
    std::string asset;             // the uploaded volume's name (PUT /api/volumes/NAME)
    std::string grid = "density";  // the float grid of that file
    Vec3 position{0.0, 0.0, 0.0};  // the grid's world origin is moved here
    Vec3 rotation_deg{0.0, 0.0, 0.0};  // XYZ Euler angles, applied X then Y then Z, about that origin
    double scale = 1.0;                // uniform, about that origin
    double density_scale = 1.0;
    Vec3 extinction{1.0, 1.0, 1.0};  // per metre per unit density
    Vec3 scattering{1.0, 1.0, 1.0};  // per metre per unit density, each channel <= extinction
    Phase phase{PhaseModel::henyey_greenstein, 0.0};  // isotropic or Henyey-Greenstein
    VolumeEmission emission;

    // The grid emission reads (its temperature grid or its emission grid); "" where it emits nothing.
    const std::string& emission_grid() const;
    bool operator==(const DensityVolume&) const = default;
};

// How many lights, objects and volumes a scene may hold.
inline constexpr size_t kMaxLights = 8;
inline constexpr size_t kMaxObjects = 64;
inline constexpr size_t kMaxVolumes = 8;
// The fewest voxels an object may ask for along its longest side (Object::resolution, when not 0).
inline constexpr uint32_t kMinObjectResolution = 16;
// The fewest voxels the scene's lattice may have along its longest axis (Volume::resolution).
inline constexpr uint32_t kMinVolumeResolution = 32;

struct SceneDocument {
    Camera camera;
    Image image;
    // Keyed by name (1..64 characters of [A-Za-z0-9_.-]), so that a merge patch edits, adds or removes
    // one by its key. A document in the older form, with one `light` and one `object`, means a
    // collection of one under the names "light" and "object".
    std::map<std::string, Light> lights{{"light", Light{}}};
    std::map<std::string, Object> objects{{"object", Object{}}};
    Medium medium;
    // Keyed like objects; none by default (the homogeneous medium alone).
    std::map<std::string, DensityVolume> volumes;
    Volume volume;
    Photons photons;
    Floor floor;
    Environment environment;

    // The first object by name: the one object of a document in the older form.
    Object& object() { return objects.begin()->second; }
    const Object& object() const { return objects.begin()->second; }

    bool operator==(const SceneDocument&) const = default;
};

// A rejected document or edit: `pointer` is the JSON pointer of the offending value, `rule` what it broke.
class ValidationError : public std::runtime_error {
public:
    ValidationError(std::string pointer, std::string rule);
    const std::string& pointer() const { return pointer_; }
    const std::string& rule() const { return rule_; }

private:
    std::string pointer_;
    std::string rule_;
};

// Hard limits that keep a request from exhausting the service; the daemon may lower them by flags.
struct Limits {
    uint32_t max_resolution = 512;
    uint32_t max_photons = 1u << 24;
    uint32_t max_image_side = 4096;
};

// A viewer's own view of a scene (a WebSocket session's `view` setting): its image size and, unless it
// follows the document's, its camera. Never stored and never a revision: the document's camera and
// image size stay the scene's saved view (what exports, `refract render` and new viewers start from).
struct View {
    uint32_t width = 0;  // 0 (with height 0): the document's image size
    uint32_t height = 0;
    std::optional<Camera> camera;  // nullopt: the document's camera

    bool operator==(const View&) const = default;
};

// Reads a view `{"width", "height", "camera"}`: width and height required (integers within
// limits.max_image_side), camera a whole camera as in the document (members left out take their
// defaults; null or absent: follow the document's). Checked whole by the document's own rules. Throws
// ValidationError with pointers under `base` (the view's place in its message).
View parse_view(const nlohmann::json& j, const Limits& limits, const std::string& base = "/view");
// `document` as the view shows it: its image size and camera replaced where the view has its own.
SceneDocument seen_through(SceneDocument document, const View& view);

// True for a member, upload or environment name: 1 to 64 characters of [A-Za-z0-9_.-], not "." or "..".
bool valid_name(std::string_view name);

// Builds a document from JSON (missing fields take defaults). Throws ValidationError.
SceneDocument parse_scene(const nlohmann::json& j, const Limits& limits = {});
// The full document as JSON, every field present; parse_scene(to_json(d)) == d.
nlohmann::json to_json(const SceneDocument& d);
// Applies an RFC 7396 merge patch to `current` and validates the result; `current` is never modified.
SceneDocument apply_merge_patch(const SceneDocument& current, const nlohmann::json& patch,
                                const Limits& limits = {});

}  // namespace refract::protocol
