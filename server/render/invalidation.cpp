#include "render/invalidation.h"

#include <algorithm>

#include "render/transport_inputs.h"

namespace refract::scene {

std::string pass_names(PassSet passes) {
    std::string out;
    const std::pair<Pass, const char*> names[] = {{kVoxelize, "voxelize"}, {kIndexField, "index_field"},
                                                  {kOctree, "octree"}, {kPhotons, "photons"}, {kView, "view"},
                                                  {kToneMap, "tone_map"}};
    for (const auto& [pass, name] : names) {
        if (!(passes & pass)) continue;
        if (!out.empty()) out += ",";
        out += name;
    }
    return out;
}

namespace {

// Whether the volumes lie elsewhere: one added or removed, or another grid or transform.
bool volumes_placed_apart(const protocol::SceneDocument& before, const protocol::SceneDocument& after) {
    if (before.volumes.size() != after.volumes.size()) return true;
    for (auto a = before.volumes.begin(), b = after.volumes.begin(); a != before.volumes.end(); ++a, ++b) {
        const protocol::DensityVolume &x = a->second, &y = b->second;
        if (a->first != b->first || x.asset != y.asset || x.grid != y.grid || x.position != y.position ||
            x.rotation_deg != y.rotation_deg || x.scale != y.scale)
            return true;
    }
    return false;
}

}  // namespace

PassSet passes_invalidated(const protocol::SceneDocument& before, const protocol::SceneDocument& after) {
    PassSet stale = 0;
    // Objects pair up by name; one added or removed changes the lattice and the field.
    const bool same_names = before.objects.size() == after.objects.size() &&
                            std::equal(before.objects.begin(), before.objects.end(), after.objects.begin(),
                                       [](const auto& a, const auto& b) { return a.first == b.first; });
    if (!same_names) return kAllPasses;
    bool materials = false, scattering = false;
    for (auto a_it = before.objects.begin(), b_it = after.objects.begin(); a_it != before.objects.end(); ++a_it, ++b_it) {
        const protocol::Object& a = a_it->second;
        const protocol::Object& b = b_it->second;
        // Geometry: the voxelize pass onwards (it voxelizes the objects whose world mesh changed only).
        // An object's resolution sets the lattice's voxel, so it changes everything.
        if (a.mesh != b.mesh || a.position != b.position || a.rotation_deg != b.rotation_deg || a.scale != b.scale ||
            a.resolution != b.resolution ||
            (a.index_field == protocol::IndexFieldKind::grid) != (b.index_field == protocol::IndexFieldKind::grid) ||
            a.grid != b.grid)
            stale |= kAllPasses;
        // The index itself: index field onwards (coverage is reused).
        if (a.index_field != b.index_field || a.ior != b.ior || a.maxwell_n0 != b.maxwell_n0)
            stale |= kIndexField | kOctree | kPhotons | kView | kToneMap;
        // The octree's leaves keep n within epsilon in every channel, so dispersion changes them too.
        if (a.abbe != b.abbe) stale |= kOctree | kPhotons | kView | kToneMap;
        materials = materials || a.extinction != b.extinction || a.fresnel != b.fresnel || !(a.film == b.film);
        scattering = scattering || a.scattering != b.scattering || !(a.phase == b.phase);
    }
    // The lattice: everything.
    if (!(before.volume.resolution == after.volume.resolution) || before.volume.smoothing != after.volume.smoothing ||
        !(before.volume.bounds == after.volume.bounds) || before.volume.margin != after.volume.margin)
        stale |= kAllPasses;
    if (before.medium.ior != after.medium.ior) stale |= kIndexField | kOctree | kPhotons | kView | kToneMap;
    if (before.volume.octree_epsilon != after.volume.octree_epsilon) stale |= kOctree | kPhotons | kView | kToneMap;
    // What photons see: the light, their number, extinction (Beer-Lambert) and the medium's fade, whether
    // the boundary reflects (and through what film) and where the floor stops them;
    // and whether they deposit at all (only where something scatters).
    if (!(before.lights == after.lights) || !(before.photons == after.photons) || materials ||
        before.medium.extinction != after.medium.extinction || before.medium.fade != after.medium.fade ||
        before.floor.enabled != after.floor.enabled ||
        before.floor.height != after.floor.height || scene::any_scattering(before) != scene::any_scattering(after))
        stale |= kPhotons | kView | kToneMap;
    // Photons that scatter (random walks) see scattering and phase functions too.
    const bool walks = before.photons.max_bounces > 0 || after.photons.max_bounces > 0;
    if (walks && (scattering || before.medium.scattering != after.medium.scattering || !(before.medium.phase == after.medium.phase)))
        stale |= kPhotons | kView | kToneMap;
    // Volumes add to the medium photons cross (their field is resampled); without bounds the lattice
    // holds them, so one that moves, or another grid, may move it: everything.
    if (!(before.volumes == after.volumes)) stale |= kPhotons | kView | kToneMap;
    if (!after.volume.bounds && volumes_placed_apart(before, after)) stale |= kAllPasses;
    // An environment that lights the scene (before or after the edit) sends photons: any change of it
    // reruns them.
    if (!(before.environment == after.environment) &&
        (scene::environment_lights(before) || scene::environment_lights(after)))
        stale |= kPhotons | kView | kToneMap;
    // Only the viewing pass reads scattering, phase functions, the floor's look, an environment that lights
    // nothing (only rays that leave the scene see the sky), the camera and the image size.
    if (!(before.camera == after.camera) || before.image.width != after.image.width ||
        before.image.height != after.image.height || scattering || before.medium.scattering != after.medium.scattering ||
        !(before.medium.phase == after.medium.phase) || !(before.floor == after.floor) ||
        !(before.environment == after.environment))
        stale |= kView | kToneMap;
    // Exposure is display only: the resident linear frame is tone-mapped again.
    if (before.image.exposure != after.image.exposure) stale |= kToneMap;
    return stale;
}

}  // namespace refract::scene
