// The scene document turned into what the transport passes read: the frame's parameters per light
// (materials, each light and its photon emitter, fixed-point scales, the floor's caustic map footprint,
// the camera), how colour travels, and the questions about the document the passes' variants depend on.
#pragma once

#include <vector>

#include "passes/environment_light.h"
#include "passes/grid_geometry.h"
#include "passes/transport_params.h"
#include "protocol/scene_document.h"
#include "fresnel.h"
#include "temporal.h"
#include "transport.h"

namespace refract::scene {

struct TransportOptions {
    bool fixed_step = false;   // photons step one shell step everywhere (the unaccelerated reference)
    float shell_step = 1.0f;   // voxels, where n varies (octree level 0)
    float view_step = 1.0f;    // voxels, eye-ray step where the medium scatters
    float reflected_view_step = 1.0f;  // the view step of reflected eye paths, in view steps
    float traced_reflection_share = FRESNEL_EYE_TRACED_SHARE;  // below it a reflected eye path goes straight
    bool neighbour_footprints = true;  // RunOptions::neighbour_footprints
    uint32_t max_level = 0;    // octree levels present
    uint32_t radiance_factor = 1;  // index-field voxels per radiance voxel along each axis (1 or 2)
    bool direct_light = true;  // unbent light in closed form (DirectLightPass) rather than by photons
    // World spheres (centre, radius) that hold every gradient of n and every object (VolumeStage::bending):
    // a light traces photons only along the rays that may meet one. Empty: over its whole emitter.
    std::vector<glm::vec4> bending;
    uint32_t photon_batch = 0;  // progressive refinement: which batch of photons (0: the document's seed)
    float photon_history = 0.0f;    // RunOptions::photon_history
    uint32_t history_frame = 0;     // RunOptions::history_frame
    uint32_t view_sample = 0;   // progressive refinement: which eye-ray sample per pixel (0: the centre)
    uint32_t view_jitter = 0;   // RunOptions::view_jitter
    uint32_t bounce_cap = protocol::kMaxBounces;  // most of photons.max_bounces taken (interactive: fewer)
    const passes::EnvironmentLight* environment = nullptr;  // the document's environment (nullptr: lights nothing)
    // What the volumes emit (MediumField::emitted_power, W, the channels' mean; 0: nothing) and the
    // largest channel over that mean (MediumField::emission_channel_ratio).
    double volume_emission_power = 0.0;
    double volume_emission_ratio = 1.0;
};

// The frame's parameters, once per light whose photons run (each with its light_* and emit_* fields,
// photon_flux, photon_info, stepping and direct_light; TransportParams::light_set.y numbers them), in the
// order of document.lights; the first also serves the viewing pass. Never empty.
// The viewing pass's pinhole camera from the document's: the eye and tan(fov / 2), and the orthonormal
// forward, right and up its rays are built from.
shaders::TemporalCamera pinhole_camera(const protocol::Camera& camera);

std::vector<shaders::TransportParams> make_transport_params(const protocol::SceneDocument& document,
                                                            const passes::GridGeometry& grid,
                                                            const TransportOptions& options);

// How the colour channels travel (CHANNELS_*, TRANSPORT_CONSTANT_CHANNELS): dispersive where the object
// has an Abbe number; else grey where extinction is the same in every channel, in the medium and in the
// object, no film colours what it reflects and no environment lights the scene (photons then keep the
// light's colour from emission to deposit); else RGB.
uint32_t transport_channels(const protocol::SceneDocument& document);

// Whether every light that shines has the same colour up to a factor (grey transport needs it).
bool lights_share_colour(const protocol::SceneDocument& document);

// The octree's epsilon for the index field as stored (the reference channel's): volume.octree_epsilon
// over the largest dispersion scale, so that n varies by less than epsilon within a leaf in every
// channel.
float octree_epsilon(const protocol::SceneDocument& document);

// Scattering events per photon a frame's random walks take: photons.max_bounces up to `cap`, 0 where
// nothing scatters (PHOTON_CONSTANT_RANDOM_WALKS is on when this is not 0).
uint32_t photon_bounces(const protocol::SceneDocument& document, uint32_t cap);

// An object's index just inside its outer boundary: the uniform object's, a Luneburg lens's 1, a Maxwell
// fish-eye's n0 / 2; the medium's for an imported grid (no boundary).
double surface_index(const protocol::Object& object, const protocol::Medium& medium);

// Whether an object's boundary reflects: Fresnel on and an index step at its boundary. A graded field
// (Luneburg, Maxwell) reflects at its outer boundary only, where its surface index lies above the
// medium's: n then rises inwards away from the shell's midpoint, which is crossed nowhere inside
// (fresnel.glsl). Imported grids never reflect.
bool reflects(const protocol::Object& object, const protocol::Medium& medium);
// Whether that boundary carries a thin film: it reflects and has a thickness.
bool has_film(const protocol::Object& object, const protocol::Medium& medium);
// Whether any object's boundary reflects (TRANSPORT_CONSTANT_FRESNEL), or carries a film
// (TRANSPORT_CONSTANT_FILM).
bool fresnel_reflects(const protocol::SceneDocument& document);
bool film_reflects(const protocol::SceneDocument& document);

// An object's material as the table of a scene of several objects holds it (TRANSPORT_CONSTANT_MATERIALS);
// the first object's fills TransportParams' object_*, shell and film.
shaders::Material material_for(const protocol::Object& object, const protocol::Medium& medium,
                               const passes::GridGeometry& grid);

// Whether anything scatters: photons deposit into the radiance grid (and direct light is computed) only then.
bool any_scattering(const protocol::SceneDocument& document);

// Whether the document's environment lights the scene: uniform or image with some radiance and `lights`
// on (the built-in sky is a backdrop only).
bool environment_lights(const protocol::SceneDocument& document);

// What the environment pass makes the document's environment of; `image` is the map an image
// environment names (ignored otherwise).
passes::EnvironmentSource environment_source(const protocol::SceneDocument& document, const image::EnvironmentMap* image);

}  // namespace refract::scene
