#include "render/transport_inputs.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "phase.h"
#include "render/medium_field.h"

namespace refract::scene {

namespace {

using protocol::LightType;
using protocol::PhaseModel;

glm::vec3 vec(const protocol::Vec3& v) {
    return {static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])};
}

uint32_t phase_model(PhaseModel m) {
    switch (m) {
        case PhaseModel::isotropic: return PHASE_ISOTROPIC_ID;
        case PhaseModel::schlick: return PHASE_SCHLICK_ID;
        case PhaseModel::henyey_greenstein: return PHASE_HG_ID;
    }
    return PHASE_ISOTROPIC_ID;
}

std::array<glm::vec3, 8> corners(const passes::GridGeometry& grid) {
    const glm::vec3 lo = grid.origin, hi = grid.max_corner();
    std::array<glm::vec3, 8> c;
    for (int i = 0; i < 8; ++i) c[static_cast<size_t>(i)] = glm::vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    return c;
}

// A unit vector perpendicular to unit vector a (any will do; this one is never parallel to a).
glm::vec3 unit_across(glm::vec3 a) {
    return glm::normalize(std::abs(a.x) < 0.9f ? glm::cross(a, glm::vec3(1, 0, 0)) : glm::cross(a, glm::vec3(0, 1, 0)));
}

// Largest power of two not above x (x >= 1).
float power_of_two_below(double x) { return static_cast<float>(std::exp2(std::floor(std::log2(std::max(x, 1.0))))); }

}  // namespace

uint32_t transport_channels(const protocol::SceneDocument& document) {
    if (document.object().abbe > 0.0) return CHANNELS_DISPERSIVE;  // every object's (the document's rule)
    auto grey = [](const auto& rgb) { return rgb[0] == rgb[1] && rgb[1] == rgb[2]; };
    const bool objects_grey = std::all_of(document.objects.begin(), document.objects.end(),
                                          [&](const auto& named) { return grey(named.second.extinction); });
    // An emitting volume's photons have their own colours, not the light's.
    const bool volumes_grey = std::all_of(document.volumes.begin(), document.volumes.end(), [&](const auto& named) {
        return grey(named.second.extinction) && !named.second.emission.emits();
    });
    return grey(document.medium.extinction) && objects_grey && volumes_grey && !film_reflects(document) &&
                   lights_share_colour(document) && !environment_lights(document)
               ? CHANNELS_GREY
               : CHANNELS_RGB;
}

bool lights_share_colour(const protocol::SceneDocument& document) {
    // Grey transport keeps one fluence and gives it the first light's colour (grey_colour): right only if
    // every light that shines has that colour up to a factor.
    const protocol::Vec3* first = nullptr;
    for (const auto& [name, light] : document.lights) {
        const auto& c = light.color;
        if (light.intensity <= 0.0 || c[0] + c[1] + c[2] <= 0.0) continue;
        if (first == nullptr) {
            first = &c;
            continue;
        }
        const auto& f = *first;
        const double a = f[0] + f[1] + f[2], b = c[0] + c[1] + c[2];
        for (size_t i = 0; i < 3; ++i)
            if (std::abs(f[i] * b - c[i] * a) > 1e-9 * a * b) return false;
    }
    return true;
}

double surface_index(const protocol::Object& object, const protocol::Medium& medium) {
    switch (object.index_field) {
        case protocol::IndexFieldKind::uniform: return object.ior;
        case protocol::IndexFieldKind::luneburg: return 1.0;  // sqrt(2 - (r / R)^2) at r = R
        case protocol::IndexFieldKind::maxwell: return 0.5 * object.maxwell_n0;  // n0 / (1 + (r / R)^2) at r = R
        case protocol::IndexFieldKind::grid: break;
    }
    return medium.ior;
}

bool reflects(const protocol::Object& object, const protocol::Medium& medium_around) {
    if (!object.fresnel) return false;
    const double surface = surface_index(object, medium_around), medium = medium_around.ior;
    switch (object.index_field) {
        case protocol::IndexFieldKind::uniform: return std::abs(surface - medium) > 1e-4;
        // n rises inwards from its surface value, so the shell's midpoint is crossed at the outer boundary
        // only (never inside) where the surface lies above the medium.
        case protocol::IndexFieldKind::luneburg:
        case protocol::IndexFieldKind::maxwell: return surface > medium + 1e-4;
        case protocol::IndexFieldKind::grid: break;  // no boundary: the field is given everywhere
    }
    return false;
}

bool has_film(const protocol::Object& object, const protocol::Medium& medium) {
    return reflects(object, medium) && (object.film.top_nm > 0.0 || object.film.bottom_nm > 0.0);
}

bool fresnel_reflects(const protocol::SceneDocument& document) {
    return std::any_of(document.objects.begin(), document.objects.end(),
                       [&](const auto& named) { return reflects(named.second, document.medium); });
}

bool film_reflects(const protocol::SceneDocument& document) {
    return std::any_of(document.objects.begin(), document.objects.end(),
                       [&](const auto& named) { return has_film(named.second, document.medium); });
}

bool any_scattering(const protocol::SceneDocument& document) {
    const auto& m = document.medium.scattering;
    double most = std::max({m[0], m[1], m[2]});
    for (const auto& [name, object] : document.objects) {
        const auto& o = object.scattering;
        most = std::max({most, o[0], o[1], o[2]});
    }
    for (const auto& [name, density] : document.volumes) {
        const auto& v = density.scattering;
        most = std::max(most, std::max({v[0], v[1], v[2]}) * density.density_scale);
    }
    return most > 0.0;
}

uint32_t photon_bounces(const protocol::SceneDocument& document, uint32_t cap) {
    return any_scattering(document) ? std::min(document.photons.max_bounces, cap) : 0u;
}

float octree_epsilon(const protocol::SceneDocument& document) {
    const glm::vec3 scales = passes::dispersion_scales(document.object().abbe);
    return static_cast<float>(document.volume.octree_epsilon) / std::max({scales.r, scales.g, scales.b, 1.0f});
}

namespace {

shaders::LightParams light_params(const protocol::Light& light) {
    shaders::LightParams l{};
    uint32_t type = LIGHT_POINT;
    if (light.type == LightType::spot) type = LIGHT_SPOT;
    if (light.type == LightType::directional) type = LIGHT_DIRECTIONAL;
    l.position = glm::vec4(vec(light.position), std::cos(glm::radians(static_cast<float>(light.cone_deg))));
    l.direction = glm::vec4(glm::normalize(vec(light.direction)), 0.0f);
    l.power = glm::vec4(vec(light.color) * static_cast<float>(light.intensity), 0.0f);
    l.type = glm::uvec4(type, 0u, 0u, 0u);
    return l;
}

// A light's photon emitter around the grid (a cone from a point or spot light, a rectangle across a
// directional light's beam) and the flux it sends through it (W per channel).
struct Emitter {
    glm::vec4 axis, u, v, origin;
    glm::vec3 flux;
};

Emitter emitter_for(const shaders::LightParams& light, const passes::GridGeometry& grid) {
    const glm::vec3 centre = 0.5f * (grid.origin + grid.max_corner());
    const float bound_radius = 0.5f * glm::length(grid.max_corner() - grid.origin);
    const glm::vec3 power(light.power);
    Emitter e{};
    if (light.type.x == LIGHT_DIRECTIONAL) {
        // A rectangle perpendicular to the light covering the grid's projection, just in front of it.
        const glm::vec3 d(light.direction);
        const glm::vec3 u = unit_across(d);
        const glm::vec3 v = glm::cross(d, u);
        glm::vec3 lo(1e30f), hi(-1e30f);
        for (const auto& c : corners(grid)) {
            const glm::vec3 s(glm::dot(c - centre, u), glm::dot(c - centre, v), glm::dot(c - centre, d));
            lo = glm::min(lo, s);
            hi = glm::max(hi, s);
        }
        const float before = lo.z - 0.01f * bound_radius;
        e.axis = glm::vec4(d, 1.0f);
        e.u = glm::vec4((hi.x - lo.x) * u, 0.0f);
        e.v = glm::vec4((hi.y - lo.y) * v, 0.0f);
        e.origin = glm::vec4(centre + lo.x * u + lo.y * v + before * d, 1.0f);
        e.flux = power * (hi.x - lo.x) * (hi.y - lo.y);
        return e;
    }
    // A cone from the light around the grid's bounding sphere (the whole sphere of directions when the
    // light is inside it); a spot's own cone when that is the smaller, contained one.
    const glm::vec3 light_position(light.position);
    const float cos_spot = light.position.w;
    const glm::vec3 to_centre = centre - light_position;
    const float distance = glm::length(to_centre);
    glm::vec3 axis(0.0f, -1.0f, 0.0f);
    float cos_cone = -1.0f;
    if (distance > bound_radius * 1.0001f) {
        axis = to_centre / distance;
        cos_cone = std::sqrt(1.0f - (bound_radius / distance) * (bound_radius / distance));
    }
    if (light.type.x == LIGHT_SPOT) {
        const float spot_half = std::acos(cos_spot);
        const float bound_half = std::acos(cos_cone);
        const float between = std::acos(std::clamp(glm::dot(axis, glm::vec3(light.direction)), -1.0f, 1.0f));
        if (between + spot_half <= bound_half) {
            axis = glm::vec3(light.direction);
            cos_cone = cos_spot;
        }
    }
    e.axis = glm::vec4(axis, cos_cone);
    const glm::vec3 u = unit_across(axis);
    e.u = glm::vec4(u, 0.0f);
    e.v = glm::vec4(glm::cross(axis, u), 0.0f);
    e.origin = glm::vec4(light_position, 1.0f);
    e.flux = power * (2.0f * std::numbers::pi_v<float> * (1.0f - cos_cone));
    return e;
}

// Where a light's photons go: a part of its emitter (TransportParams::photon_cone, photon_part,
// photon_rect) and that part's share of the emitter's samples (1: the whole emitter).
struct PhotonPart {
    glm::vec4 cone{0.0f}, across{0.0f}, rect{0.0f, 0.0f, 1.0f, 1.0f};
    double share = 1.0;
    // Of `emitted` photons over the whole emitter, those in the part (at least one where any are).
    uint32_t traced(uint32_t emitted) const {
        if (share >= 1.0 || emitted == 0) return emitted;
        return std::max(1u, static_cast<uint32_t>(std::ceil(emitted * share)));
    }
};

// The photons' part of a light's emitter `e`: the rays that may meet one of options.bending (world spheres
// that hold every gradient of n and every object). Photons that would go straight
// land where the direct light (or, with nothing that scatters, the floor's closed form) already holds
// their light, from `near_world` (metres) from the light on; random walks scatter photons anywhere.
PhotonPart photon_part_for(const shaders::LightParams& light, const Emitter& e,
                           const passes::GridGeometry& grid, float near_world,
                           const protocol::SceneDocument& document, const TransportOptions& options) {
    PhotonPart part;
    const std::vector<glm::vec4>& bending = options.bending;
    const bool direct_elsewhere =
        photon_bounces(document, options.bounce_cap) == 0 &&
        (!any_scattering(document) || (options.direct_light && document.volumes.empty()));
    if (!direct_elsewhere || bending.empty()) return part;
    const protocol::Floor& floor = document.floor;
    const float floor_height = static_cast<float>(floor.height);
    if (light.type.x == LIGHT_DIRECTIONAL) {
        // Light that rises from below the floor is the floor's shadow, not a straight ray's.
        if (floor.enabled && light.direction.y >= 0.0f) return part;
        const glm::vec3 u(e.u), v(e.v), corner(e.origin);
        glm::vec2 lo(1.0f), hi(0.0f);
        for (const glm::vec4& b : bending) {
            const glm::vec3 rel = glm::vec3(b) - corner;
            const glm::vec2 at(glm::dot(rel, u) / glm::dot(u, u), glm::dot(rel, v) / glm::dot(v, v));
            const glm::vec2 reach(b.w / glm::length(u), b.w / glm::length(v));
            lo = glm::min(lo, at - reach);
            hi = glm::max(hi, at + reach);
        }
        lo = glm::clamp(lo, 0.0f, 1.0f);
        hi = glm::clamp(hi, 0.0f, 1.0f);
        const double share = static_cast<double>(std::max(hi.x - lo.x, 0.0f)) *
                             static_cast<double>(std::max(hi.y - lo.y, 0.0f));
        if (share <= 0.0 || share >= 1.0) return part;
        part.rect = glm::vec4(lo, hi);
        part.across.w = 1.0f;
        part.share = share;
        return part;
    }
    const glm::vec3 light_position(light.position);
    if (floor.enabled && light_position.y <= floor_height) return part;
    // Every point of the grid at least `near` from the light, or the direct light would miss the rest there.
    const glm::vec3 nearest = glm::clamp(light_position, grid.origin, grid.max_corner());
    if (glm::length(nearest - light_position) < near_world) return part;
    glm::vec3 towards(0.0f);
    for (const glm::vec4& b : bending) {
        const glm::vec3 to = glm::vec3(b) - light_position;
        if (glm::length(to) <= b.w) return part;  // the light inside: every direction may bend
        towards += glm::normalize(to);
    }
    if (glm::length(towards) < 1e-6f) return part;
    const glm::vec3 axis = glm::normalize(towards);
    float half_angle = 0.0f;
    for (const glm::vec4& b : bending) {
        const glm::vec3 to = glm::vec3(b) - light_position;
        const float distance = glm::length(to);
        const float off_axis = std::acos(std::clamp(glm::dot(axis, to / distance), -1.0f, 1.0f));
        half_angle = std::max(half_angle, off_axis + std::asin(b.w / distance));
    }
    if (half_angle >= 0.5f * std::numbers::pi_v<float>) return part;
    const float cos_part = std::cos(half_angle);
    const double share = (1.0 - static_cast<double>(cos_part)) / (1.0 - static_cast<double>(e.axis.w));
    if (share >= 1.0) return part;
    part.cone = glm::vec4(axis, cos_part);
    part.across = glm::vec4(unit_across(axis), 1.0f);
    part.share = share;
    return part;
}

}  // namespace

shaders::Material material_for(const protocol::Object& object, const protocol::Medium& medium,
                               const passes::GridGeometry& grid) {
    shaders::Material m{};
    const double surface = surface_index(object, medium);
    m.extinction = glm::vec4(vec(object.extinction), static_cast<float>(surface));
    m.scattering = glm::vec4(vec(object.scattering), static_cast<float>(object.phase.g));
    // A film's thickness goes from its top value at the object's top to its bottom value at its bottom
    // (the built-in meshes reach scale above and below position).
    const auto to_voxel_y = [&](double y) { return (static_cast<float>(y) - grid.origin.y) / grid.voxel_size; };
    m.shell = glm::vec4(reflects(object, medium) ? 1.0f : 0.0f, static_cast<float>(0.5 * (surface + medium.ior)),
                        to_voxel_y(object.position[1] + object.scale), to_voxel_y(object.position[1] - object.scale));
    m.film = glm::vec4(static_cast<float>(object.film.ior), static_cast<float>(object.film.top_nm),
                       static_cast<float>(object.film.bottom_nm), 0.0f);
    m.model = glm::uvec4(phase_model(object.phase.model), 0u, 0u, 0u);
    return m;
}

namespace {

// The medium's fade (TransportParams::medium_fade): at most a quarter of the grid's shortest side, so that
// its middle keeps the full density, and none for a medium that neither scatters nor absorbs (where the
// density changes nothing, and the octree's leaves need not be cut). The bottom face does not fade
// where the floor, which hides what lies below it, is inside the grid.
void set_medium_fade(shaders::TransportParams& p, const protocol::SceneDocument& document,
                     const passes::GridGeometry& grid) {
    const auto& medium = document.medium;
    const bool clear = medium.extinction == protocol::Vec3{0.0, 0.0, 0.0} && medium.scattering == protocol::Vec3{0.0, 0.0, 0.0};
    const double shortest = static_cast<double>(std::min({grid.dims.x, grid.dims.y, grid.dims.z}));
    const double fade = clear ? 0.0 : std::min(medium.fade / static_cast<double>(grid.voxel_size), 0.25 * shortest);
    const bool floor_hides_bottom = document.floor.enabled && document.floor.height >= static_cast<double>(grid.origin.y);
    p.medium_fade = glm::vec4(static_cast<float>(fade), floor_hides_bottom ? -1e30f : 0.0f,
                              fade > 0.0 ? static_cast<float>(1.0 / fade) : 0.0f, 0.0f);
}

// The floor, and where its caustic map lies: where the grid's shadow under any light (and the grid
// itself) falls.
void set_floor(shaders::TransportParams& p, const protocol::Floor& floor, const passes::GridGeometry& grid,
               const std::vector<shaders::LightParams>& lights) {
    const glm::vec3 centre = 0.5f * (grid.origin + grid.max_corner());
    const float floor_height = static_cast<float>(floor.height);
    p.floor_plane = glm::vec4(floor_height, static_cast<float>(floor.checker_size), floor.enabled ? 1.0f : 0.0f,
                              floor.checker ? 1.0f : 0.0f);
    p.floor_albedo = glm::vec4(vec(floor.albedo), 0.0f);
    const float grid_extent = glm::length(grid.max_corner() - grid.origin);
    glm::vec2 lo(centre.x, centre.z), hi = lo;
    for (const auto& c : corners(grid)) {
        lo = glm::min(lo, glm::vec2(c.x, c.z));
        hi = glm::max(hi, glm::vec2(c.x, c.z));
        for (const auto& light : lights) {
            const glm::vec3 light_position(light.position), light_direction(light.direction);
            glm::vec3 hit;
            bool lands = false;
            if (light.type.x == LIGHT_DIRECTIONAL) {
                if (light_direction.y < -1e-4f && c.y > floor_height) {
                    hit = c + light_direction * ((c.y - floor_height) / -light_direction.y);
                    lands = true;
                }
            } else if (light_position.y > c.y + 1e-4f && c.y > floor_height) {
                hit = light_position +
                      (c - light_position) * ((light_position.y - floor_height) / (light_position.y - c.y));
                lands = true;
            }
            if (lands) {
                lo = glm::min(lo, glm::vec2(hit.x, hit.z));
                hi = glm::max(hi, glm::vec2(hit.x, hit.z));
            }
        }
    }
    // Refracted light spreads past the straight shadow (behind a focus, say): leave room around it.
    const float spread = 0.5f * std::max(grid.max_corner().x - grid.origin.x, grid.max_corner().z - grid.origin.z);
    lo -= spread;
    hi += spread;
    const glm::vec2 centre_xz(centre.x, centre.z);
    lo = glm::max(lo, centre_xz - 2.0f * grid_extent);
    hi = glm::min(hi, centre_xz + 2.0f * grid_extent);
    const float side = std::max(hi.x - lo.x, hi.y - lo.y) * 1.02f;
    const glm::vec2 mid = 0.5f * (lo + hi);
    p.floor_map = glm::vec4(mid.x - 0.5f * side, mid.y - 0.5f * side, side,
                            static_cast<float>(passes::floor_map_texels(grid)));

}

// The camera, the image and this refinement step's sample.
void set_camera(shaders::TransportParams& p, const protocol::SceneDocument& document, const TransportOptions& options) {
    const shaders::TemporalCamera camera = pinhole_camera(document.camera);
    p.camera_position = camera.position;
    p.camera_forward = camera.forward;
    p.camera_right = camera.right;
    p.camera_up = camera.up;
    p.image = glm::uvec4(document.image.width, document.image.height, options.neighbour_footprints ? 1u : 0u, 0u);
    p.tone = glm::vec4(std::exp2(static_cast<float>(document.image.exposure)), options.view_step,
                       options.view_step * options.reflected_view_step, options.traced_reflection_share);
    // A light drag's frame joins the photons of the frames before it as an exponential moving average.
    const float batch_weight = options.photon_history > 0.0f ? 1.0f - options.photon_history
                                                             : 1.0f / static_cast<float>(options.photon_batch + 1);
    p.refinement = glm::vec4(batch_weight,
                             1.0f / static_cast<float>(options.view_sample + 1),
                             passes::view_sample_offset(options.view_sample + options.view_jitter));
}

// The frame's parameters `p` once per light whose photons run, and the environment's photons with the
// first that has any.
std::vector<shaders::TransportParams> per_light_params(shaders::TransportParams p,
                                                       const protocol::SceneDocument& document,
                                                       const std::vector<shaders::LightParams>& lights,
                                                       const passes::GridGeometry& grid, const TransportOptions& options) {
    const bool scatters = any_scattering(document);
    // A guard against photons that never finish, not a budget: a random walk's free paths each take
    // their own steps, so the guard grows with the bounces allowed.
    const uint32_t bounces = photon_bounces(document, options.bounce_cap);
    const uint32_t max_steps = 4 * (grid.dims.x + grid.dims.y + grid.dims.z) * (1 + bounces);
    // Each light's photons, and the environment's when it lights the scene: shares of the count in
    // proportion to the flux each sends towards the grid (the channels' mean), so every photon carries
    // about the same flux. An environment sends its photons into the grid through a disc around the grid's
    // bounding sphere, facing the direction each comes from; they go with the first dispatch (its last
    // environment.z photons), as they never travel unbent (transport.h): the store of unbent light stays
    // that dispatch's light's own.
    std::vector<Emitter> emitters;
    std::vector<double> powers;
    for (const auto& light : lights) {
        emitters.push_back(emitter_for(light, grid));
        const glm::vec3 f = emitters.back().flux;
        powers.push_back((static_cast<double>(f.r) + static_cast<double>(f.g) + static_cast<double>(f.b)) / 3.0);
    }
    const passes::EnvironmentLight* lighting = options.environment;
    const float bound_radius = 0.5f * glm::length(grid.max_corner() - grid.origin);
    const float rotation = glm::radians(static_cast<float>(document.environment.rotation_deg));
    p.environment_frame = glm::vec4(std::cos(rotation), std::sin(rotation), bound_radius, 0.0f);
    if (lighting)
        p.environment = glm::uvec4(lighting->width, lighting->height, 0u,
                                   document.environment.type == protocol::EnvironmentKind::image ? 1u : 0u);
    const bool environment_photons = lighting && lighting->lights();
    double environment_power = 0.0;
    if (environment_photons) {
        const double radius = static_cast<double>(bound_radius);
        environment_power = std::numbers::pi * radius * radius * lighting->sampled;
        powers.push_back(environment_power);
        p.environment_light = glm::vec4(lighting->floor_irradiance, 0.0f);
    }
    // The volumes' emission, like the environment, sends its photons with the carrier below.
    const bool volume_photons = options.volume_emission_power > 0.0;
    if (volume_photons) powers.push_back(options.volume_emission_power);
    const std::vector<uint32_t> shares = passes::photon_shares(document.photons.count, powers);
    const uint32_t from_volumes = volume_photons ? shares.back() : 0u;
    const uint32_t from_environment = environment_photons ? shares[lights.size()] : 0u;
    // The dispatch that carries the environment's photons: the first light's that has any (the first
    // light's when none has).
    size_t carrier = 0;
    while (carrier + 1 < lights.size() && shares[carrier] == 0) ++carrier;
    std::vector<shaders::TransportParams> per_light;
    for (size_t i = 0; i < lights.size(); ++i) {
        const uint32_t emitted = shares[i];
        const uint32_t environment_share = i == carrier ? from_environment : 0u;
        const uint32_t volume_share = i == carrier ? from_volumes : 0u;
        if (emitted == 0 && environment_share == 0 && volume_share == 0) continue;
        shaders::TransportParams q = p;
        const shaders::LightParams& light = lights[i];
        const Emitter& e = emitters[i];
        // Direct light from UNBENT_MIN_DISTANCE radiance voxels (plus one, for the voxel's own extent) from
        // a point or spot light on: every voxel it reaches takes unbent deposits (transport.h).
        const float near = light.type.x == LIGHT_DIRECTIONAL
                               ? 0.0f
                               : (UNBENT_MIN_DISTANCE + 1.0f) * static_cast<float>(options.radiance_factor);
        // Of the `emitted` photons the light sends over its emitter, those in the photons' part are traced.
        const PhotonPart part = photon_part_for(light, e, grid, near * grid.voxel_size, document, options);
        const uint32_t photons = part.traced(emitted);
        q.photon_cone = part.cone;
        q.photon_part = part.across;
        q.photon_rect = part.rect;
        q.light_set.y = static_cast<uint32_t>(per_light.size());
        q.models.z = light.type.x;
        q.light_position = light.position;
        q.light_direction = light.direction;
        q.light_power = light.power;
        q.emit_axis = e.axis;
        q.emit_u = e.u;
        q.emit_v = e.v;
        q.emit_origin = e.origin;
        // The part's flux (times 1 exactly for the whole emitter).
        const glm::vec3 part_flux = e.flux * static_cast<float>(part.share);
        const glm::vec3 flux = photons > 0 ? part_flux / static_cast<float>(photons) : glm::vec3(0.0f);
        float reference = std::max({flux.r, flux.g, flux.b, 1e-30f});
        if (environment_share > 0) {
            // Environment photons carry their pixel's colour over its mean times this, at most channel_ratio.
            const double environment_flux = environment_power / environment_share;
            reference = std::max(reference, static_cast<float>(environment_flux * lighting->channel_ratio));
            q.environment.z = environment_share;
            q.environment_frame.w = static_cast<float>(environment_flux / static_cast<double>(reference));
        }
        if (volume_share > 0) {
            // A volume photon carries its voxel's colour over the colour's mean times this.
            const double volume_flux = options.volume_emission_power / volume_share;
            reference = std::max(reference, static_cast<float>(volume_flux * options.volume_emission_ratio));
            q.volume_emission.x = volume_share;
            q.volume_emission_flux.x = static_cast<float>(volume_flux / static_cast<double>(reference));
            if (environment_share > 0)  // against the reference as it now is
                q.environment_frame.w = static_cast<float>(environment_power / environment_share / static_cast<double>(reference));
        }
        q.photon_flux = glm::vec4(flux, reference);
        // Each refinement batch draws its own photons: another seed (a Weyl step, so batches never repeat
        // one), and so does each light.
        const uint32_t seed = document.photons.seed + options.photon_batch * 0x9e3779b9u +
                              static_cast<uint32_t>(i) * 0x632be5abu + options.history_frame * 0x2545f491u;
        const uint32_t count = photons + environment_share + volume_share;
        q.photon_info = glm::uvec4(count, seed, max_steps, options.fixed_step ? 1u : 0u);
        // Fixed-point scales chosen so no voxel or texel sum can overflow 2^31 even if every photon
        // deposited its full weight into it: a voxel crossing is at most sqrt(3) voxel lengths, and a net
        // flux deposit is |d|_1 <= sqrt(3) times that (transport.h), so 3 x scale per photon at most.
        const double n = static_cast<double>(count);
        q.stepping = glm::vec4(options.shell_step, 0.02f, power_of_two_below(2147483647.0 / (4.0 * n)),
                               power_of_two_below(2147483647.0 / n));
        // The floor's shadow in closed form needs only the light map's traced runs: on wherever the light's
        // photons reach a floor, fog or none.
        const bool floor_shadow = options.direct_light && document.floor.enabled && photons > 0;
        q.direct_light = glm::vec4(
            static_cast<float>(passes::light_map_texels(grid, std::max(emitted, 1u))), near,
            floor_shadow ? 1.0f : 0.0f,
            options.direct_light && scatters && photons > 0 && document.volumes.empty() ? 1.0f : 0.0f);
        per_light.push_back(q);
    }
    return per_light;
}

}  // namespace

shaders::TemporalCamera pinhole_camera(const protocol::Camera& camera) {
    const glm::vec3 eye = vec(camera.position);
    const glm::vec3 forward = glm::normalize(vec(camera.target) - eye);
    const glm::vec3 right = glm::normalize(glm::cross(forward, vec(camera.up)));
    const glm::vec3 up = glm::cross(right, forward);
    return {glm::vec4(eye, std::tan(glm::radians(static_cast<float>(camera.fov_deg)) * 0.5f)), glm::vec4(forward, 0.0f),
            glm::vec4(right, 0.0f), glm::vec4(up, 0.0f)};
}

std::vector<shaders::TransportParams> make_transport_params(const protocol::SceneDocument& document,
                                                            const passes::GridGeometry& grid,
                                                            const TransportOptions& options) {
    shaders::TransportParams p{};
    p.grid_origin = glm::vec4(grid.origin, grid.voxel_size);
    p.grid_dims = glm::uvec4(grid.dims.x, grid.dims.y, grid.dims.z, options.max_level);

    const auto& medium = document.medium;
    const auto& object = document.object();
    p.medium_extinction = glm::vec4(vec(medium.extinction), static_cast<float>(medium.ior));
    p.medium_scattering = glm::vec4(vec(medium.scattering), static_cast<float>(medium.phase.g));
    p.object_extinction = glm::vec4(vec(object.extinction), static_cast<float>(object.ior));
    p.object_scattering = glm::vec4(vec(object.scattering), static_cast<float>(object.phase.g));

    // The lights: all of them for the viewing pass, and below, per light, its photons.
    static_assert(TRANSPORT_MAX_LIGHTS == protocol::kMaxLights);
    std::vector<shaders::LightParams> lights;
    for (const auto& named : document.lights) lights.push_back(light_params(named.second));
    for (size_t i = 0; i < lights.size(); ++i) p.lights[i] = lights[i];
    p.light_set = glm::uvec4(static_cast<uint32_t>(lights.size()), 0u, 0u, 0u);
    const uint32_t bounces = photon_bounces(document, options.bounce_cap);
    p.models = glm::uvec4(phase_model(medium.phase.model), phase_model(object.phase.model), LIGHT_POINT, bounces);
    p.dispersion = glm::vec4(passes::dispersion_scales(object.abbe), 0.0f);

    set_floor(p, document.floor, grid, lights);
    set_camera(p, document, options);
    set_medium_fade(p, document, grid);
    // How passes find coverage for each coefficient, and whether photons need to deposit at all. n is
    // linear in coverage only in the field of one uniform object.
    const bool uniform_index = document.objects.size() == 1 && object.index_field == protocol::IndexFieldKind::uniform &&
                               std::abs(object.ior - medium.ior) > 1e-4;
    auto coverage_mode = [&](auto coefficients_equal) {
        const bool all_equal = std::all_of(document.objects.begin(), document.objects.end(),
                                           [&](const auto& named) { return coefficients_equal(named.second); });
        if (all_equal) return COVERAGE_CONSTANT;
        return uniform_index ? COVERAGE_FROM_INDEX : COVERAGE_FETCH;
    };
    const bool scatters = any_scattering(document);
    p.flags = glm::uvec4(0u, coverage_mode([&](const protocol::Object& o) { return medium.extinction == o.extinction; }),
                         coverage_mode([&](const protocol::Object& o) {
                             return medium.scattering == o.scattering && medium.phase == o.phase;
                         }),
                         scatters ? 1u : 0u);
    const vk::Extent3 radiance_dims = grid.coarsened(options.radiance_factor);
    p.radiance_grid = glm::uvec4(radiance_dims.x, radiance_dims.y, radiance_dims.z, options.radiance_factor);
    const shaders::Material first = material_for(object, medium, grid);
    p.shell = glm::vec4(first.extinction.w, glm::vec3(first.shell.y, first.shell.z, first.shell.w));
    p.film = first.film;
    p.materials = glm::uvec4(0u, 0u, static_cast<uint32_t>(document.objects.size()), 0u);
    // The environment: what rays that leave the scene see (view.comp, sky).
    const auto& environment = document.environment;
    const float intensity = static_cast<float>(environment.intensity);
    const bool uniform_environment = environment.type == protocol::EnvironmentKind::uniform;
    const glm::vec3 zenith = uniform_environment ? vec(environment.color) : glm::vec3(0.010f, 0.014f, 0.024f);
    const glm::vec3 horizon = uniform_environment ? vec(environment.color) : glm::vec3(0.045f, 0.050f, 0.060f);
    p.sky_zenith = glm::vec4(zenith * intensity, 0.0f);
    p.sky_horizon = glm::vec4(horizon * intensity, 0.0f);

    return per_light_params(p, document, lights, grid, options);
}

bool environment_lights(const protocol::SceneDocument& document) {
    const auto& environment = document.environment;
    if (environment.type == protocol::EnvironmentKind::sky || !environment.lights || environment.intensity <= 0.0)
        return false;
    if (environment.type == protocol::EnvironmentKind::uniform)
        return std::max({environment.color[0], environment.color[1], environment.color[2]}) > 0.0;
    return true;
}

passes::EnvironmentSource environment_source(const protocol::SceneDocument& document, const image::EnvironmentMap* image) {
    const protocol::Environment& environment = document.environment;
    passes::EnvironmentSource source;
    switch (environment.type) {
        case protocol::EnvironmentKind::sky: source.kind = passes::EnvironmentSource::Kind::sky; break;
        case protocol::EnvironmentKind::uniform: source.kind = passes::EnvironmentSource::Kind::uniform; break;
        case protocol::EnvironmentKind::image: source.kind = passes::EnvironmentSource::Kind::image; break;
    }
    source.color = glm::dvec3(environment.color[0], environment.color[1], environment.color[2]);
    source.image = image;
    source.name = environment.image;
    source.intensity = environment.intensity;
    source.lights = environment_lights(document);
    source.floor_hides_below = document.floor.enabled;
    return source;
}

}  // namespace refract::scene
