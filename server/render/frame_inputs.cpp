#include "render/frame_inputs.h"

#include <algorithm>

#include "render/scene_gpu.h"
#include "render/transport_inputs.h"

namespace refract::scene {

passes::FieldShape field_shape(const protocol::Object& object) {
    passes::FieldShape shape;
    shape.n = static_cast<float>(object.ior);
    switch (object.index_field) {
        case protocol::IndexFieldKind::uniform: shape.kind = INDEX_KIND_UNIFORM; break;
        case protocol::IndexFieldKind::luneburg: shape.kind = INDEX_KIND_LUNEBURG; break;
        case protocol::IndexFieldKind::maxwell:
            shape.kind = INDEX_KIND_MAXWELL;
            shape.n = static_cast<float>(object.maxwell_n0);
            break;
        case protocol::IndexFieldKind::grid: shape.kind = INDEX_KIND_GRID; break;
    }
    shape.sphere = glm::vec4(static_cast<float>(object.position[0]), static_cast<float>(object.position[1]),
                             static_cast<float>(object.position[2]), static_cast<float>(object.scale));
    return shape;
}

FrameInputs::Volume volume_inputs(const protocol::SceneDocument& document) {
    FrameInputs::Volume in;
    in.imported = document.object().index_field == protocol::IndexFieldKind::grid;
    in.smoothing = document.volume.smoothing;
    in.medium_ior = document.medium.ior;
    // The medium joins the objects' fields as a uniform object of its index (index_field.comp).
    protocol::Object medium;
    medium.ior = document.medium.ior;
    in.medium = field_shape(medium);
    for (const auto& [name, object] : document.objects) in.objects.emplace_back(name, field_shape(object));
    in.octree_epsilon = octree_epsilon(document);
    return in;
}

FrameInputs::Transport photon_settings(const protocol::SceneDocument& document, const RunOptions& options) {
    FrameInputs::Transport in;
    in.channels = transport_channels(document);
    in.bounces = photon_bounces(document, options.bounce_cap);
    return in;
}

FrameInputs::Transport transport_inputs(const protocol::SceneDocument& document,
                                        const passes::GridGeometry& grid,
                                        const passes::EnvironmentLight& environment,
                                        const MediumEmission& emitted, const std::vector<glm::vec4>& bending,
                                        const RunOptions& options) {
    FrameInputs::Transport in = photon_settings(document, options);
    in.fresnel = fresnel_reflects(document);
    in.film = film_reflects(document);
    TransportOptions transport;
    transport.fixed_step = options.fixed_step;
    // Eye rays step at least radiance_factor lattice voxels through fog: a voxel of the radiance grid they
    // gather from (less where objects refine the lattice), so a preview shading from its own grid takes
    // three, not two. Two cost its view 1.09-1.15x, for a frame 0.36 8-bit RMS apart whose difference from
    // the still is the same (8.571 against 8.574; docs/perf-log,
    // 2026-12-07-where-issue-41-stands-measured-directly.md). A camera drag shading from a still's grid keeps
    // its two.
    transport.view_step = std::max(options.view_step, static_cast<float>(options.radiance_factor));
    transport.reflected_view_step = options.reflected_view_step;
    transport.traced_reflection_share = options.traced_reflection_share;
    transport.neighbour_footprints = options.neighbour_footprints;
    transport.max_level = passes::octree_layout(grid.dims).max_level;
    transport.radiance_factor = options.radiance_factor * grid.light_factor;
    transport.direct_light = options.direct_light;
    // A run that records every photon's exit (a lens's focus, tested) traces the whole emitter's photons.
    if (options.photon_part && !options.record_photon_exits) transport.bending = bending;
    transport.photon_batch = options.photon_batch;
    transport.photon_history = options.photon_history;
    transport.history_frame = options.history_frame;
    transport.view_sample = options.view_sample;
    transport.view_jitter = options.view_jitter;
    transport.bounce_cap = options.bounce_cap;
    transport.environment = &environment;
    transport.volume_emission_power = emitted.power;
    transport.volume_emission_ratio = emitted.channel_ratio;
    in.lights = make_transport_params(document, grid, transport);
    if (document.objects.size() > 1)
        for (const auto& [name, object] : document.objects) in.materials.push_back(material_for(object, document.medium, grid));
    in.volumes = document.volumes;
    return in;
}

}  // namespace refract::scene
