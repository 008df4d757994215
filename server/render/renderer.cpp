#include "render/renderer.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <list>
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include "image/png.h"
#include "mesh/mesh.h"
#include "render/object_mesh.h"
#include "render/scene_gpu.h"
#include "render/scene_lattice.h"
#include "render/temporal_history.h"
#include "vk/context.h"

namespace refract::scene {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
    return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The document an interactive frame renders: the budget's image size and photon count, and the lattice
// coarsened while an object moves (the scene's resolution and each object's own, within their limits).
protocol::SceneDocument with_settings(protocol::SceneDocument document, const InteractiveSettings& settings) {
    document.image.width = settings.width;
    document.image.height = settings.height;
    document.photons.count = settings.photons;
    const uint32_t divisor = settings.lattice_divisor;
    document.volume.resolution = std::max(document.volume.resolution / divisor, std::min(document.volume.resolution, protocol::kMinVolumeResolution));
    for (auto& [name, object] : document.objects)
        if (object.resolution != 0)
            object.resolution = std::max(object.resolution / divisor, std::min(object.resolution, protocol::kMinObjectResolution));
    return document;
}


// Whether the photons of `before`'s frame still hold for `after`, a frame of a light drag: nothing but
// the view, the budget's settings and the lights' places changed, and no light moved farther than
// `radiance_voxel` (metres) where its light lands, up to `reach` metres away (its position's move plus
// what its turn sweeps there). Farther, the kernel would not hide the old light's place (TEMPORAL.md).
bool photons_still_hold(protocol::SceneDocument before, const protocol::SceneDocument& after, double radiance_voxel,
                        double reach) {
    if (before.lights.size() != after.lights.size()) return false;
    for (auto& [name, light] : before.lights) {
        const auto other = after.lights.find(name);
        if (other == after.lights.end()) return false;
        const glm::dvec3 from(light.position[0], light.position[1], light.position[2]);
        const glm::dvec3 to(other->second.position[0], other->second.position[1], other->second.position[2]);
        const glm::dvec3 d0 = glm::normalize(glm::dvec3(light.direction[0], light.direction[1], light.direction[2]));
        const glm::dvec3 d1 = glm::normalize(glm::dvec3(other->second.direction[0], other->second.direction[1],
                                                        other->second.direction[2]));
        const double turn = std::acos(std::clamp(glm::dot(d0, d1), -1.0, 1.0));
        if (glm::length(to - from) + reach * turn >= radiance_voxel) return false;
        light.position = other->second.position;
        light.direction = other->second.direction;
    }
    before.camera = after.camera;
    before.image = after.image;
    before.photons.count = after.photons.count;
    return before == after;
}

// The milliseconds of a frame spent in passes whose cost the image size and photon count do not set
// (a geometry edit while dragging), kept out of the budget's measurements.
double volume_ms(const FrameResult& frame) {
    double ms = 0.0;
    for (const auto& t : frame.timings)
        if (t.name == "voxelize" || t.name == "index_field" || t.name == "octree") ms += t.gpu_ms;
    return ms;
}

// The milliseconds of an interactive frame spent at the viewer's size whatever size it traced: temporal
// reuse or the upscale, and the encode of its full-size frame.
double viewer_ms(const FrameResult& frame) {
    double ms = 0.0;
    for (const auto& t : frame.timings)
        if (t.name == "temporal" || t.name == "upscale" || t.name == "encode") ms += t.host_ms;
    return ms;
}

// The timings of a frame that ran refinement steps: one entry per pass, summed over the steps.
void add_timing(std::vector<PassTiming>& timings, const std::string& name, double gpu_ms) {
    for (auto& t : timings)
        if (t.name == name) {
            t.gpu_ms += gpu_ms;
            return;
        }
    timings.push_back({name, gpu_ms, 0.0});
}

double photon_ms(const FrameResult& frame) {
    for (const auto& t : frame.timings)
        if (t.name == "photons") return t.gpu_ms;
    return 0.0;
}

// The smallest volume.resolution the protocol accepts: a warm-up volume builds in milliseconds.
constexpr uint32_t kWarmUpResolution = 32;

// The assets a document names, resolved before anything resident is touched: an unknown name must not be.
struct ResolvedAssets {
    std::map<std::string, std::shared_ptr<const mesh::Mesh>> meshes;  // each object's, by name
    std::shared_ptr<const IndexGrid> grid;
    std::shared_ptr<const image::EnvironmentMap> environment;
    Densities densities;  // each volume's grid, by the member's name
};

ResolvedAssets resolve(const protocol::SceneDocument& document, const Assets& assets) {
    ResolvedAssets resolved;
    for (const auto& [name, object] : document.objects) {
        if (object.index_field == protocol::IndexFieldKind::grid) {
            resolved.grid = assets.grid ? assets.grid(object.grid) : nullptr;
            if (!resolved.grid) throw RenderError("index field grid '" + object.grid + "' is not loaded");
            if (!has_cubic_voxels(*resolved.grid)) throw RenderError("index field grid voxels must be cubic (within 1%)");
            continue;
        }
        auto mesh = base_mesh(object, assets.mesh);
        if (!mesh) throw RenderError("mesh '" + object.mesh + "' of object '" + name + "' is not a built-in or an uploaded mesh");
        resolved.meshes.emplace(name, std::move(mesh));
    }
    if (document.environment.type == protocol::EnvironmentKind::image) {
        resolved.environment = assets.environment ? assets.environment(document.environment.image) : nullptr;
        if (!resolved.environment)
            throw RenderError("environment '" + document.environment.image + "' is not a built-in or an uploaded one");
    }
    for (const auto& [name, member] : document.volumes) {
        VolumeGrids grids;
        grids.density = assets.density ? assets.density(member.asset, member.grid) : nullptr;
        if (!grids.density) throw RenderError("volume '" + member.asset + "' of /volumes/" + name + " is not an uploaded one");
        if (member.emission.emits()) {
            grids.emission = assets.density ? assets.density(member.asset, member.emission_grid()) : nullptr;
            if (!grids.emission)
                throw RenderError("grid '" + member.emission_grid() + "' of volume '" + member.asset + "' (/volumes/" + name +
                                  "/emission) is not in the uploaded one");
        }
        resolved.densities.emplace(name, std::move(grids));
    }
    return resolved;
}

// The objects in world space, fitted to the lattice (what the voxelize pass reads).
WorldMeshes worlds_of(const protocol::SceneDocument& document, const ResolvedAssets& resolved) {
    WorldMeshes worlds;
    for (const auto& [name, mesh] : resolved.meshes) worlds.emplace(name, world_mesh(document.objects.at(name), *mesh));
    return worlds;
}

// Device memory the scene `document` holds once rendered, estimated on the lattice it asks for before
// anything is allocated (the objects' boxes in it, or the imported grid's own lattice).
int64_t needed_bytes(const protocol::SceneDocument& document, const WorldMeshes& worlds, const IndexGrid* grid,
                     const image::EnvironmentMap* environment, const Densities& densities) {
    const passes::GridGeometry g = grid ? passes::GridGeometry{{}, 1.0f, {grid->nx, grid->ny, grid->nz}} : scene::grid_for(document, worlds, densities);
    uint64_t object_voxels = 0;
    std::map<std::string, passes::ObjectBox> boxes;
    if (grid) object_voxels = g.dims.count();
    else
        boxes = object_boxes(g, worlds, document.volume.smoothing);
    for (const auto& [name, box] : boxes) object_voxels += box.box.dims.count();
    // An atlas wider than any device allows is refused when the scene is built; here it counts as is.
    const uint64_t field_voxels =
        field_atlas_for(g, boxes, grid || document.objects.size() < 2, std::numeric_limits<uint32_t>::max()).dims.count();
    return estimate_scene_bytes(g, field_voxels, object_voxels, g.coarsened(g.light_factor).count(), document.image.width,
                                document.image.height) +
           estimate_environment_bytes(environment) + static_cast<int64_t>(medium_field_bytes(plan_medium_field(g, document.volumes, densities)));
}

// Still frames of other views of the scene kept for their refinement (ViewStage::ParkedFrame): a few
// viewers refining at once take turns without starting their eye-ray samples over.
constexpr size_t kMaxParkedViews = 4;

// Viewers whose drags a scene keeps a temporal history for (render/temporal_history.h), the least
// recently used dropped past this.
constexpr size_t kMaxHistories = 4;

struct ParkedView {
    protocol::SceneDocument document;  // as rendered: the scene seen through that view
    uint32_t level = 0;
    ViewStage::ParkedFrame frame;
};

// Whether `next` holds other objects than `held` (by name): an example loaded, a document imported, an
// object added or removed.
bool other_objects(const protocol::SceneDocument& held, const protocol::SceneDocument& next) {
    return !std::equal(held.objects.begin(), held.objects.end(), next.objects.begin(), next.objects.end(),
                       [](const auto& a, const auto& b) { return a.first == b.first; });
}

// What a frame's eye rays are: its document and assets but for what only lights them (the lights, the
// photons, the exposure), at the viewer's size. A light drag's frames whose eye rays are a still frame's
// take each viewer pixel's own eye ray from that still (RunOptions::still_ends).
struct EyeRays {
    protocol::SceneDocument document;
    std::map<std::string, std::shared_ptr<const mesh::Mesh>> meshes;
    std::shared_ptr<const IndexGrid> grid;
    Densities densities;

    bool operator==(const EyeRays&) const = default;
};

EyeRays eye_rays(protocol::SceneDocument document, const ResolvedAssets& resolved, uint32_t width,
                 uint32_t height) {
    document.lights.clear();
    document.photons = {};
    document.image.exposure = 0.0;
    document.image.width = width;
    document.image.height = height;
    return {std::move(document), resolved.meshes, resolved.grid, resolved.densities};
}

// Whether `a` and `b` are the same scene, seen through views that may differ.
bool same_scene(const protocol::SceneDocument& a, const protocol::SceneDocument& b) {
    return a == protocol::seen_through(b, {a.image.width, a.image.height, a.camera});
}

// A scene's resident GPU state and what it was built from.
struct ResidentScene {
    std::unique_ptr<SceneGpu> gpu;
    protocol::SceneDocument document;  // as last rendered
    std::map<std::string, std::shared_ptr<const mesh::Mesh>> meshes;  // each object's, by name
    std::shared_ptr<const IndexGrid> grid;
    std::shared_ptr<const image::EnvironmentMap> environment;
    Densities densities;
    uint64_t last_used = 0;
    uint32_t level = 0;  // refinement level of the resident still frame (0: the frame is interactive or partial)
    uint32_t lattice_divisor = 1;  // the interactive lattice's (InteractiveSettings), 1 after a still frame
    uint32_t history_frames = 0;   // frames of a light drag whose photons the radiance grid holds a share of
    FrameBudget budget;  // this scene's dynamic resolution
    std::vector<ParkedView> parked;  // least recently rendered first
    std::map<std::string, std::unique_ptr<TemporalHistory>> histories;  // by FrameOptions::history
    uint64_t stills = 0;  // still frames made, which number them for TemporalHistory::seeded_from
    // The eye rays of the still frame whose ends the scene keeps (SceneGpu::has_still_ends).
    std::optional<EyeRays> still_ends;
};

// Whether `held` keeps the ends of a still frame whose eye rays were `rays` (at the viewer's size).
bool keeps_still_ends(const ResidentScene& held, const EyeRays& rays) {
    return held.still_ends == rays &&
           held.gpu->has_still_ends(rays.document.image.width, rays.document.image.height);
}

// Device memory the views of a scene hold beside its frame: parked frames, temporal histories and the
// interactive frame at its viewer's size.
int64_t view_bytes(const ResidentScene& held) {
    int64_t bytes = held.gpu ? held.gpu->upscale_bytes() : 0;
    for (const ParkedView& view : held.parked) bytes += view.frame.bytes();
    for (const auto& [key, history] : held.histories) bytes += history->bytes();
    return bytes;
}

// The history of viewer `key` (made when new, the least recently used dropped past kMaxHistories), seeded
// from the scene's newest still frame when that is at the viewer's size and newer than what the history
// holds: the resident one, or the one switch_view just parked for this frame's view.
TemporalHistory& history_for(ResidentScene& held, PassKit& kit, const std::string& key,
                             const protocol::SceneDocument& requested, uint64_t now) {
    auto it = held.histories.find(key);
    if (it == held.histories.end()) {
        if (held.histories.size() >= kMaxHistories)
            held.histories.erase(std::min_element(held.histories.begin(), held.histories.end(), [](const auto& a, const auto& b) {
                return a.second->last_used < b.second->last_used;
            }));
        it = held.histories.emplace(key, std::make_unique<TemporalHistory>(kit)).first;
    }
    TemporalHistory& history = *it->second;
    history.last_used = now;
    const bool sized = held.gpu->width() == requested.image.width && held.gpu->height() == requested.image.height;
    if (held.stills != history.seeded_from) {
        if (held.level > 0 && (held.gpu->built() & kView) && sized) {
            history.seed(held.gpu->hdr_buffer(), held.document);
        } else if (!held.parked.empty() && held.parked.back().frame.width == requested.image.width &&
                   held.parked.back().frame.height == requested.image.height) {
            history.seed(held.parked.back().frame.hdr, held.parked.back().document);
        }
        history.seeded_from = held.stills;
    }
    return history;
}

// Before a frame of `requested`: the resident still frame is parked when `requested` shows the same scene
// through another view, and a still frame comes back from the parked ones when one is of its view and the
// resident state was last made by a still frame of this scene (its photon settings; whether the grid
// still holds the frame's batches is for the plan). Parked frames of an older scene state are dropped.
void switch_view(ResidentScene& held, const protocol::SceneDocument& requested, Quality quality) {
    std::erase_if(held.parked, [&](const ParkedView& view) { return !same_scene(view.document, requested); });
    const bool resident_still = held.level > 0 && (held.gpu->built() & kView);
    if (resident_still && held.document != requested && same_scene(held.document, requested)) {
        if (held.parked.size() == kMaxParkedViews) held.parked.erase(held.parked.begin());
        held.parked.push_back({held.document, held.level, held.gpu->park_view()});
        held.level = 0;
    }
    if (quality != Quality::still || !same_scene(held.document, requested)) return;
    const auto view = std::find_if(held.parked.begin(), held.parked.end(),
                                   [&](const ParkedView& parked) { return parked.document == requested; });
    if (view == held.parked.end() || held.document == requested) return;
    held.gpu->restore_view(std::move(view->frame));
    held.document = view->document;
    held.level = view->level;
    held.parked.erase(view);
}

// What the resident frame was rendered with, interactive or still (an interactive frame's document holds
// its settings).
InteractiveSettings settings_of(const ResidentScene& held) {
    return {held.document.image.width, held.document.image.height, held.document.photons.count, held.lattice_divisor};
}

// What a frame is to be, decided from the request and the resident scene before anything is built.
struct FramePlan {
    protocol::SceneDocument document;  // as rendered: an interactive frame's holds its budget's settings
    InteractiveSettings settings;      // interactive frames
    PassSet stale = kAllPasses;
    uint32_t level = 1;           // the refinement level the frame holds
    uint32_t resident_level = 0;  // the level whose linear frame (or, with the view stale, photons) is resident
};

// The first refinement step a frame of `plan` runs: level 1 (the frame itself), or the resident level
// where its passes are stale.
uint32_t first_step(const FramePlan& plan) {
    return plan.stale != 0 && plan.resident_level > 0 ? plan.resident_level : plan.resident_level + 1;
}

// The passes `next` reruns over what `held` holds (everything when nothing is held).
PassSet stale_against(const ResidentScene* held, const protocol::SceneDocument& next, const ResolvedAssets& resolved) {
    if (!held) return kAllPasses;
    PassSet stale = passes_invalidated(held->document, next);
    if (held->meshes != resolved.meshes || held->grid != resolved.grid) stale |= kAllPasses;
    // A re-uploaded image lights the scene anew.
    if (held->environment != resolved.environment) stale |= kPhotons | kView | kToneMap;
    // A re-uploaded volume changes the medium the photons cross, and without bounds the lattice around it.
    if (held->densities != resolved.densities) stale |= next.volume.bounds ? kPhotons | kView | kToneMap : kAllPasses;
    return held->gpu->passes_for(stale);
}

// Still frames refine in order from level 1 (refinement_at). One continues from the resident still
// frame when the edit leaves it valid but for its tone (exposure), that frame's level is not above its
// own and, to refine it further, the radiance grid holds that level's batches; else from the photon
// batches the grid holds, when it is a still frame's and holds no more than this level's (their view at
// pixel centres is the frame of the level with that many); else from new photons.
void plan_still_levels(FramePlan& plan, const ResidentScene& held, const FrameOptions& options) {
    PassSet& stale = plan.stale;
    const uint32_t batches =
        stale & kPhotons ? 0u : held.gpu->photon_batches(plan.document, run_options_for(Quality::still));
    // A still that may resume takes the highest level the resident state gives for no more work: its
    // frame re-toned, else the view over its batches (levels 1..kMaxPhotonBatches hold as many as their
    // number).
    const uint32_t retoned =
        !(stale & ~kToneMap) && batches == refinement_at(held.level).photon_batches ? held.level : 0u;
    for (const uint32_t resumed : {retoned, batches}) {
        if (resumed > plan.level && resumed <= std::min(options.resume_up_to, kMaxRefinementLevel)) {
            plan.level = resumed;
            break;
        }
    }
    if (!(stale & ~kToneMap) && held.level != 0 && held.level <= plan.level &&
        (held.level == plan.level || batches == refinement_at(held.level).photon_batches)) {
        plan.resident_level = held.level;
    } else if (batches > 0 && batches <= refinement_at(plan.level).photon_batches) {
        plan.resident_level = batches;
        stale |= kView | kToneMap;
    } else {
        stale |= kPhotons | kView | kToneMap;
    }
}

}  // namespace

RunOptions run_options_for(Quality quality) {
    RunOptions options;
    // Still frames deposit sampled too: their photon trace takes a quarter less, for 2-5% more photon
    // noise in the frame, what 5-10% fewer photons would add
    // (docs/perf-log/2026-12-04-sampled-deposits-for-stills.md).
    options.sampled_deposits = true;
    if (quality == Quality::interactive) {
        options.view_step = 2.0f;
        options.traced_reflection_share = FRESNEL_PREVIEW_TRACED_SHARE;
        options.radiance_factor = 3;
        options.adaptive_view = true;
        options.neighbour_footprints = false;
        options.adaptive_density = true;
        options.bounce_cap = kInteractiveBounces;
    }
    return options;
}


struct Renderer::Impl {
    Impl(vk::Context& ctx, RendererOptions opts) : context(ctx), options(opts), kit(ctx) {}

    // The least recently used scene other than `keep` and those whose frame is in progress; end() if none.
    std::map<std::string, ResidentScene>::iterator least_recent(const std::string& keep) {
        auto oldest = scenes.end();
        for (auto it = scenes.begin(); it != scenes.end(); ++it)
            if (it->first != keep && !rendering.contains(it->first) &&
                (oldest == scenes.end() || it->second.last_used < oldest->second.last_used))
                oldest = it;
        return oldest;
    }

    void evict_least_recent(const std::string& keep) {
        while (scenes.size() > std::max<size_t>(options.max_resident_scenes, 1)) {
            auto oldest = least_recent(keep);
            if (oldest == scenes.end()) return;
            scenes.erase(oldest);
        }
    }

    // What a frame of `requested` is to be over what `held` holds.
    FramePlan plan(const ResidentScene* held, const FrameBudget& budget, const protocol::SceneDocument& requested,
                   const ResolvedAssets& resolved, const FrameOptions& asked);
    // Drops least recently used scenes until the frame fits the device memory budget. False when it fits
    // only by evicting a scene whose frame is in progress (the frame must wait); RenderError when never.
    bool make_room(const std::string& scene_id, const ResidentScene* held, const FramePlan& plan,
                   const WorldMeshes& worlds, const ResolvedAssets& resolved);
    // Runs the frame's steps (level 1, then each refinement level). False when one gave way.
    bool run_steps(ResidentScene& resident, const FramePlan& plan, const WorldMeshes& worlds,
                   const ResolvedAssets& resolved, const RunOptions& frame_options,
                   const std::function<bool()>& give_way, FrameResult& frame);
    // The frame's levels and its PNG: an interactive frame with a viewer's `temporal` history is taken into
    // it, one traced smaller without one is upscaled (true), and either is sent at the viewer's size
    // (`requested`'s).
    // `still_ends`: the scene keeps the ends of a still frame with the same eye rays as this one.
    bool finish_frame(ResidentScene& resident, const FramePlan& plan, const RunOptions& frame_options,
                      const protocol::SceneDocument& requested, TemporalHistory* temporal, bool still_ends,
                      FrameResult& frame);
    // Records what the resident state was built from.
    void keep(ResidentScene& resident, const protocol::SceneDocument& document, const ResolvedAssets& resolved,
              uint32_t level, uint32_t lattice_divisor);
    // Called in a catch block: drops the scene and rethrows what failed, as a RenderError where the scene is
    // past this device's limits or memory.
    [[noreturn]] void drop_after_failure(const std::string& scene_id);

    vk::Context& context;
    RendererOptions options;
    PassKit kit;
    std::map<std::string, ResidentScene> scenes;
    std::set<std::string> rendering;  // scenes whose render() is in progress (one, or two nested)
    uint64_t clock = 0;
    mutable std::mutex mutex;  // guards `scenes` for the read-only queries from other threads
};

Renderer::Renderer(vk::Context& context, RendererOptions options)
    : impl_(std::make_unique<Impl>(context, options)) {}

Renderer::~Renderer() = default;

Refinement refinement_at(uint32_t level) {
    level = std::clamp(level, 1u, kMaxRefinementLevel);
    return {std::min(level, kMaxPhotonBatches), level > kMaxPhotonBatches ? level - kMaxPhotonBatches + 1 : 1u};
}

FramePlan Renderer::Impl::plan(const ResidentScene* held, const FrameBudget& budget, const protocol::SceneDocument& requested,
                               const ResolvedAssets& resolved, const FrameOptions& asked) {
    FramePlan plan;
    plan.document = requested;
    if (asked.quality == Quality::interactive) {
        // What the edit reruns if the resident frame's settings were kept (a still frame's too: its photon
        // count keeps its radiance grid) decides which of them may change.
        const InteractiveSettings resident = held ? settings_of(*held) : InteractiveSettings{};
        const PassSet would = held ? stale_against(held, with_settings(requested, resident), resolved) : kAllPasses;
        plan.settings = budget.choose(requested, (would & kPhotons) != 0, (would & kView) != 0,
                                      held ? &resident : nullptr, asked.budget_ms);
        // A frame that builds the volume (an object dragged, a scene loaded) does so on a coarse lattice,
        // and the frames after it keep that lattice until a still frame: the volume passes scale with the
        // voxels, and at the document's lattice they alone would outlast the budget. A frame of other
        // objects than the resident ones builds every object at once (an example loaded, a document
        // imported: the gallery's eight objects took 0.2 s of volume passes and 0.5 s of photons, resolve
        // and spread at kDragLatticeDivisor on two cores), so it takes the coarser kLoadLatticeDivisor.
        // Uploaded index grids keep theirs.
        if (held && !resolved.grid) {
            if (other_objects(held->document, requested)) plan.settings.lattice_divisor = kLoadLatticeDivisor;
            else if (would & kVoxelize) plan.settings.lattice_divisor = kDragLatticeDivisor;
            else plan.settings.lattice_divisor = resident.lattice_divisor;
        }
        plan.document = with_settings(requested, plan.settings);
    }
    plan.stale = stale_against(held, plan.document, resolved);
    // A volume built on a coarse lattice took a preview's rays (render()): a still voxelizes again, also
    // where the lattice did not change (a resolution at its floor).
    if (asked.quality == Quality::still && held && held->lattice_divisor > 1) plan.stale |= kVoxelize;
    if (asked.quality == Quality::still) {
        plan.level = std::clamp(asked.level, 1u, kMaxRefinementLevel);
        if (held) plan_still_levels(plan, *held, asked);
    }
    return plan;
}

bool Renderer::Impl::make_room(const std::string& scene_id, const ResidentScene* held, const FramePlan& plan,
                               const WorldMeshes& worlds, const ResolvedAssets& resolved) {
    const int64_t budget = options.device_memory_budget;
    // Checked before anything is built: a new volume, or a new environment map on the old one.
    const bool rebuild = (plan.stale & kVoxelize) != 0;
    const bool new_environment = !held || held->environment != resolved.environment;
    if (budget <= 0 || !(rebuild || new_environment)) return true;
    // What a resident scene holds (the lattice's own voxels stand for its boxes: an estimate).
    auto held_by = [](const ResidentScene& r) {
        const passes::GridGeometry& held_grid = r.gpu->grid();
        return r.gpu->built() ? estimate_scene_bytes(held_grid, r.gpu->field_atlas().dims.count(), held_grid.dims.count(),
                                                     held_grid.coarsened(held_grid.light_factor).count(), r.gpu->width(),
                                                     r.gpu->height()) +
                                    estimate_environment_bytes(r.environment.get()) + view_bytes(r)
                              : int64_t{0};
    };
    auto it = scenes.find(scene_id);
    const int64_t replaced = it != scenes.end() ? held_by(it->second) : 0;
    const int64_t need = rebuild ? needed_bytes(plan.document, worlds, resolved.grid.get(), resolved.environment.get(), resolved.densities)
                                 : replaced - estimate_environment_bytes(held->environment.get()) +
                                       estimate_environment_bytes(resolved.environment.get());
    // This scene's old state is released before the new one is made. Make room by dropping least
    // recently used scenes (their documents live on in the store).
    while (context.allocated_bytes() - replaced + need > budget) {
        auto oldest = least_recent(scene_id);
        if (oldest == scenes.end()) {
            if (!rendering.empty()) return false;
            throw RenderError("scene needs about " + std::to_string(need >> 20) + " MiB of device memory; the budget is " +
                              std::to_string(budget >> 20) + " MiB");
        }
        scenes.erase(oldest);
    }
    return true;
}

bool Renderer::Impl::run_steps(ResidentScene& resident, const FramePlan& plan, const WorldMeshes& worlds,
                               const ResolvedAssets& resolved, const RunOptions& frame_options,
                               const std::function<bool()>& give_way, FrameResult& frame) {
    uint64_t photon_steps = 0;
    // The first step runs the stale passes: level 1's, or those of the resident level.
    for (uint32_t step = first_step(plan); step <= plan.level; ++step) {
        // Level 1 is the frame itself; each level after it adds one photon batch (rerunning the view at
        // pixel centres) until the batches are all in, then one jittered eye-ray sample per pixel.
        RunOptions run_options = frame_options;
        run_options.still_ends = frame_options.still_ends && step == first_step(plan);
        PassSet passes = plan.stale;
        if (step > std::max(plan.resident_level, 1u)) {
            const Refinement now = refinement_at(step), before = refinement_at(step - 1);
            if (now.photon_batches > before.photon_batches) {
                run_options.photon_batch = now.photon_batches - 1;
                passes = kPhotons;
            } else {
                run_options.view_sample = now.samples_per_pixel - 1;
                passes = kView;
            }
        }
        // Each step runs in parts and gives way between them when the caller says other work waits.
        run_options.give_way = give_way;
        const RunStats stats =
            resident.gpu->run(passes, plan.document, worlds, resolved.grid.get(), run_options, resolved.environment.get(),
                              resolved.densities);
        if (stats.gave_way) {
            // What the GPU holds now: this document, with part of a step the frame does not hold; a step
            // that gave way before its view leaves the frame of the level before it.
            keep(resident, plan.document, resolved, resident.gpu->built() & kView ? step - 1 : 0,
                 plan.settings.lattice_divisor);
            return false;
        }
        frame.rerun |= stats.ran;
        frame.voxelized.insert(frame.voxelized.end(), stats.voxelized.begin(), stats.voxelized.end());
        for (const auto& [name, ms] : stats.gpu_ms) add_timing(frame.timings, name, ms);
        frame.photons_traced += stats.photons_entered;
        photon_steps += stats.photon_steps;
    }
    frame.mean_steps_per_photon =
        frame.photons_traced ? static_cast<double>(photon_steps) / static_cast<double>(frame.photons_traced) : 0.0;
    return true;
}

void Renderer::Impl::keep(ResidentScene& resident, const protocol::SceneDocument& document, const ResolvedAssets& resolved,
                          uint32_t level, uint32_t lattice_divisor) {
    resident.document = document;
    resident.lattice_divisor = lattice_divisor;
    resident.meshes = resolved.meshes;
    resident.grid = resolved.grid;
    resident.environment = resolved.environment;
    resident.densities = resolved.densities;
    resident.level = level;
}

FrameResult Renderer::render(const std::string& scene_id, const protocol::SceneDocument& requested,
                             const Assets& assets, const FrameOptions& options) {
    const auto start = Clock::now();
    const Quality quality = options.quality;
    const ResolvedAssets resolved = resolve(requested, assets);

    std::unique_lock lock(impl_->mutex);
    auto it = impl_->scenes.find(scene_id);
    // A scene prepared ahead (prepare) or whose last step gave way holds some passes built: the rest run.
    const ResidentScene* held = it != impl_->scenes.end() && it->second.gpu->built() != 0 ? &it->second : nullptr;
    if (held) switch_view(it->second, requested, quality);
    const FrameBudget unmeasured;
    const FrameBudget& budget = it != impl_->scenes.end() ? it->second.budget : unmeasured;
    const FramePlan plan = impl_->plan(held, budget, requested, resolved, options);
    // The objects in world space fit the lattice; needed only when the volume is rebuilt.
    const WorldMeshes worlds = plan.stale & kVoxelize ? worlds_of(plan.document, resolved) : WorldMeshes{};
    FrameResult frame;
    if (!impl_->make_room(scene_id, held, plan, worlds, resolved)) {
        frame.outcome = FrameResult::Outcome::deferred;
        return frame;
    }
    it = impl_->scenes.find(scene_id);
    if (it == impl_->scenes.end()) {
        ResidentScene resident;
        resident.gpu = std::make_unique<SceneGpu>(impl_->kit);
        it = impl_->scenes.emplace(scene_id, std::move(resident)).first;
    }
    ResidentScene& resident = it->second;
    resident.last_used = ++impl_->clock;
    // Pinned while its frame is in progress: a frame rendered between its parts must not evict it.
    impl_->rendering.insert(scene_id);
    struct Unpin {
        Impl& impl;
        const std::string& scene_id;
        ~Unpin() {
            std::lock_guard relock(impl.mutex);
            impl.rendering.erase(scene_id);
        }
    } unpin{*impl_, scene_id};
    lock.unlock();
    // What the queue does between parts (other scenes' frames) is not this frame's time.
    double paused_ms = 0.0;
    std::function<bool()> give_way;
    if (options.give_way)
        give_way = [&] {
            const auto paused = Clock::now();
            const bool stop = options.give_way();
            paused_ms += ms_since(paused);
            return stop;
        };
    // An interactive frame whose photons need not run shades from the resident radiance grid, whatever
    // quality made it: the first frame of a camera drag after a still frame runs no photons. Photons
    // that run go into the interactive grid.
    RunOptions frame_options = run_options_for(quality);
    frame_options.paced_parts = options.paced_parts;
    // On the coarse lattice of an object drag, radiance voxels of about the size the other interactive
    // frames have (in the scene's units).
    const uint32_t divisor = plan.settings.lattice_divisor;
    frame_options.radiance_factor = std::max(1u, (frame_options.radiance_factor + divisor / 2) / divisor);
    // and a preview's rays per voxel column (the cast and gather a third of their time; plan() has the
    // still after such a frame voxelize again).
    if (divisor > 1) frame_options.voxelize.subsamples = passes::VoxelizePass::kPreviewSubsamples;
    if (quality == Quality::interactive && !(plan.stale & kPhotons))
        frame_options = resident.gpu->with_resident_photons(frame_options);
    // A light dragged a little keeps part of the last frames' photons: smooth light while it moves.
    const passes::GridGeometry& lattice = resident.gpu->grid();
    const bool history = quality == Quality::interactive && (plan.stale & kPhotons) && resident.level == 0 &&
                         resident.gpu->photon_batches(plan.document, frame_options) > 0 &&
                         photons_still_hold(resident.document, plan.document,
                                            static_cast<double>(lattice.voxel_size) *
                                                (lattice.light_factor * frame_options.radiance_factor),
                                            static_cast<double>(glm::length(lattice.max_corner() - lattice.origin)));
    resident.history_frames = history ? resident.history_frames + 1 : 0;
    TemporalHistory* temporal = quality == Quality::interactive && !options.history.empty()
                                    ? &history_for(resident, impl_->kit, options.history, requested, resident.last_used)
                                    : nullptr;
    if (temporal) frame_options.view_jitter = temporal->next_jitter();
    // Traced smaller than its viewer without a history: sent at the viewer's size all the same, its floor
    // and sky found again for every pixel (passes::ViewUpscalePass).
    frame_options.view_ends = quality == Quality::interactive && !temporal &&
                              (plan.document.image.width != requested.image.width ||
                               plan.document.image.height != requested.image.height);
    if (history) {
        frame_options.photon_history = kPhotonHistory;
        frame_options.history_frame = resident.history_frames;
    }
    // A still frame keeps its eye rays' ends for the light drags after it (its first step's view writes
    // them), where they fit: past kStillEndsMaxPixels such drags take their traced pixels' ends alone.
    const uint64_t pixels = uint64_t{requested.image.width} * requested.image.height;
    frame_options.still_ends = quality == Quality::still && pixels <= kStillEndsMaxPixels;
    const EyeRays rays = eye_rays(plan.document, resolved, requested.image.width, requested.image.height);
    const bool still_ends = frame_options.view_ends && keeps_still_ends(resident, rays);
    // Which eye rays the kept ends are is known again once the view that writes them is whole (the first
    // step's, at the pixels' centres).
    const bool writes_still_ends = frame_options.still_ends && (plan.stale & kView);
    if (writes_still_ends) resident.still_ends.reset();
    try {
        if (!impl_->run_steps(resident, plan, worlds, resolved, frame_options, give_way, frame)) {
            frame.outcome = FrameResult::Outcome::superseded;  // the resident state is whole; only the frame was not made
            return frame;
        }
        if (writes_still_ends) resident.still_ends = rays;
        const bool upscaled =
            impl_->finish_frame(resident, plan, frame_options, requested, temporal, still_ends, frame);
        if (options.linear) frame.linear = upscaled ? resident.gpu->read_viewer_hdr() : resident.gpu->read_hdr();
    } catch (...) {
        impl_->drop_after_failure(scene_id);
    }
    impl_->keep(resident, plan.document, resolved, quality == Quality::still ? plan.level : 0,
                plan.settings.lattice_divisor);
    if (quality == Quality::still) ++resident.stills;
    if (quality == Quality::interactive) {
        const double photons = photon_ms(frame);
        const double viewer = temporal || frame_options.view_ends ? viewer_ms(frame) : 0.0;
        resident.budget.observe(requested, plan.settings, photons, viewer,
                                ms_since(start) - paused_ms - photons - volume_ms(frame) - viewer);
    }
    std::lock_guard relock(impl_->mutex);
    impl_->evict_least_recent(scene_id);
    return frame;
}

bool Renderer::Impl::finish_frame(ResidentScene& resident, const FramePlan& plan,
                                  const RunOptions& frame_options, const protocol::SceneDocument& requested,
                                  TemporalHistory* temporal, bool still_ends, FrameResult& frame) {
    frame.level = plan.level;
    frame.refinement = refinement_at(plan.level);
    // An interactive frame may be shaded from a still frame's refined grid.
    frame.refinement.photon_batches = resident.gpu->photon_batches(plan.document, frame_options);
    frame.photons = uint64_t{frame.refinement.photon_batches} * plan.document.photons.count;
    frame.width = frame.traced_width = resident.gpu->width();
    frame.height = frame.traced_height = resident.gpu->height();
    if (temporal) {
        const auto temporal_start = Clock::now();
        temporal->add(resident.gpu->hdr_buffer(), frame.width, frame.height, requested, (frame.rerun & kView) != 0);
        frame.timings.push_back({"temporal", 0.0, ms_since(temporal_start)});
        frame.width = temporal->width();
        frame.height = temporal->height();
    }
    // A frame that only re-toned keeps the ends of the view before it, when that view kept them.
    const bool upscaled = frame_options.view_ends && resident.gpu->has_view_ends();
    if (upscaled) {
        const auto upscale_start = Clock::now();
        resident.gpu->upscale(requested.image.width, requested.image.height, still_ends);
        frame.still_eye_rays = still_ends;
        frame.timings.push_back({"upscale", 0.0, ms_since(upscale_start)});
        frame.width = requested.image.width;
        frame.height = requested.image.height;
    }
    const auto encode_start = Clock::now();
    const auto pixels = temporal ? temporal->read_ldr() : upscaled ? resident.gpu->read_viewer_ldr() : resident.gpu->read_ldr();
    frame.png = image::encode_png(pixels, frame.width, frame.height);
    frame.timings.push_back({"encode", 0.0, ms_since(encode_start)});
    return upscaled;
}

void Renderer::Impl::drop_after_failure(const std::string& scene_id) {
    // Partially rebuilt state is not trusted: drop it, the next render rebuilds from the document.
    {
        std::lock_guard relock(mutex);
        scenes.erase(scene_id);
    }
    // A scene past this device's limits or memory is unrenderable as asked, not a device fault.
    try {
        throw;
    } catch (const vk::LimitError& e) {
        throw RenderError(std::string("the scene cannot be rendered on this device: ") + e.what());
    } catch (const vk::Error& e) {
        if (e.result() != VK_ERROR_OUT_OF_DEVICE_MEMORY) throw;
        throw RenderError(std::string("the scene does not fit in this device's memory: ") + e.what());
    }
}

namespace {

// A warm-up's copy of `document`: the smallest image and photon count, which no pipeline depends on.
protocol::SceneDocument warm_up_copy(protocol::SceneDocument document) {
    document.image.width = document.image.height = FrameBudget::kMinSide;
    document.photons.count = FrameBudget::kMinPhotons;
    return document;
}

// Not a scene id the store accepts, so no scene's resident state or frame budget is touched; evicted
// when the warm-up ends, however it ends.
struct WarmUpScene {
    Renderer& renderer;
    const std::string id = " warm-up";
    ~WarmUpScene() { renderer.evict(id); }
};

}  // namespace

void Renderer::warm_up(const protocol::SceneDocument& document, const Assets& assets, Quality quality) {
    protocol::SceneDocument reduced = warm_up_copy(document);
    reduced.volume.resolution = kWarmUpResolution;
    WarmUpScene scene{*this};
    FrameOptions options;
    options.quality = quality;
    render(scene.id, reduced, assets, options);
    // A drag's frames are traced a fraction of their viewer's size and upscaled by a pipeline for each
    // share of the traced pixels' loads (upscale_shared_loads: each lane its own four over half the
    // viewer's size, two loads a lane down to 2/7 of it, one below), which lavapipe compiles at its first
    // dispatch; after a still frame, by the variant that takes each viewer pixel's eye ray from the still's
    // ends. So, at viewers 1.5, 2 and 4 times the reduced frame's size: (a still there, then) a drag's
    // frame traced at the budget's least, the reduced size. (Without the still, the first two frames of
    // the first orbit compiled theirs: 40-68 ms of upscale, not 20.)
    for (const uint32_t viewer_side :
         {3 * FrameBudget::kMinSide / 2, 2 * FrameBudget::kMinSide, 4 * FrameBudget::kMinSide}) {
        protocol::SceneDocument viewed = reduced;
        viewed.image.width = viewed.image.height = viewer_side;
        if (quality == Quality::still) render(scene.id, viewed, assets, options);
        for (auto& [name, light] : viewed.lights) light.position[1] += 0.5;
        FrameOptions drag;
        drag.quality = Quality::interactive;
        drag.budget_ms = 1.0;
        render(scene.id, viewed, assets, drag);
    }
}

void Renderer::warm_up_load(const protocol::SceneDocument& before, const protocol::SceneDocument& loaded,
                            const Assets& assets) {
    protocol::SceneDocument shown = warm_up_copy(before);
    shown.volume.resolution = kWarmUpResolution;
    WarmUpScene scene{*this};
    FrameOptions options;
    options.quality = Quality::interactive;
    render(scene.id, shown, assets, options);
    render(scene.id, warm_up_copy(loaded), assets, options);
}

bool Renderer::prepare(const std::string& scene_id, const protocol::SceneDocument& document, const Assets& assets,
                       const std::function<bool()>& stop) {
    const ResolvedAssets resolved = resolve(document, assets);
    const WorldMeshes worlds = worlds_of(document, resolved);
    std::unique_lock lock(impl_->mutex);
    if (impl_->scenes.contains(scene_id)) return false;  // rendered already: nothing to prepare
    // Only into room there is: a scene nobody has asked for yet never evicts one that somebody has.
    if (impl_->scenes.size() >= std::max<size_t>(impl_->options.max_resident_scenes, 1)) return false;
    const int64_t budget = impl_->options.device_memory_budget;
    if (budget > 0 &&
        impl_->context.allocated_bytes() + needed_bytes(document, worlds, resolved.grid.get(), resolved.environment.get(), resolved.densities) > budget)
        return false;
    ResidentScene& resident = impl_->scenes[scene_id];
    resident.gpu = std::make_unique<SceneGpu>(impl_->kit);
    resident.last_used = ++impl_->clock;
    lock.unlock();
    // The photons of the scene's first interactive frame: their count does not depend on the image size
    // (the viewer's own), and a budget that has measured nothing chooses it from the document alone.
    const InteractiveSettings settings = resident.budget.choose(document, true, true, nullptr, kDefaultBudgetMs);
    // What photons cost sizes the first frame that traces them (a light drag's; a camera drag's frames
    // shade from the resident grid and measure none): measured at the floor's count too, so that the
    // budget knows the pass's fixed part from that frame on. From one count it took the cost for one in
    // proportion to the count, and the default scene's first light-drag frame traced more photons than
    // the floor's, for 54-59 ms against 35-37 at the floor (docs/perf-log/2026-12-07-first-drag-frames.md).
    InteractiveSettings fewest = settings;
    fewest.photons = FrameBudget::floor_photons(document);
    std::vector<std::pair<PassSet, InteractiveSettings>> runs = {
        {kVoxelize, settings}, {kIndexField, settings}, {kOctree, settings}};
    if (fewest.photons != settings.photons) runs.emplace_back(kPhotons, fewest);
    runs.emplace_back(kPhotons, settings);
    // What the resident photons were traced with: a stop may come between the two counts.
    InteractiveSettings built = settings;
    try {
        // One pass a submission, so that a request waits for one pass at most; render() runs what is left.
        for (const auto& [pass, run] : runs) {
            if (stop()) break;
            RunOptions run_options = run_options_for(Quality::interactive);
            run_options.limit = pass;
            const RunStats stats =
                resident.gpu->run(pass, with_settings(document, run), worlds, resolved.grid.get(),
                                  run_options, resolved.environment.get(), resolved.densities);
            if (pass == kPhotons) {
                resident.budget.observe(document, run, stats.gpu_ms.front().second, 0.0, 0.0);
                built = run;
            }
        }
    } catch (...) {
        evict(scene_id);  // partially built state is not trusted
        throw;
    }
    resident.document = with_settings(document, built);
    resident.meshes = resolved.meshes;
    resident.grid = resolved.grid;
    resident.environment = resolved.environment;
    resident.densities = resolved.densities;
    resident.level = 0;  // no frame: render() runs the view and tone map (and what the stop left)
    return true;
}

void Renderer::evict(const std::string& scene_id) {
    std::lock_guard lock(impl_->mutex);
    impl_->scenes.erase(scene_id);
}

size_t Renderer::resident_scenes() const {
    std::lock_guard lock(impl_->mutex);
    return impl_->scenes.size();
}

int64_t Renderer::device_bytes() const { return impl_->context.allocated_bytes(); }

}  // namespace refract::scene
