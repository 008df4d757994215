#include "render/scene_gpu.h"

#include "assets/render_error.h"
#include "passes/octree.h"
#include "passes/transport_params.h"
#include "render/scene_lattice.h"
#include "render/transport_inputs.h"

namespace refract::scene {
namespace {

// Where the view leaves its eye rays' ends: a still's only from its first sample (at the pixels' centres,
// where the upscale's rays go).
ViewStage::Ends view_ends(const RunOptions& options) {
    if (options.view_ends) return ViewStage::Ends::traced;
    return options.still_ends && options.view_sample == 0 ? ViewStage::Ends::still : ViewStage::Ends::none;
}

}  // namespace

PassKit::PassKit(vk::Context& ctx)
    : context(ctx),
      voxelize(ctx),
      index_field(ctx),
      octree(ctx),
      direct_light(ctx),
      photon_trace(ctx),
      radiance_resolve(ctx),
      radiance_spread(ctx),
      view(ctx),
      view_upscale(ctx),
      tone_map(ctx),
      temporal_neighbourhood(ctx),
      temporal_reuse(ctx) {}

int64_t estimate_scene_bytes(const passes::GridGeometry& grid, uint64_t field_voxels, uint64_t object_voxels,
                             uint64_t radiance_voxels, uint32_t width, uint32_t height) {
    // Per field voxel: index field (16), coverage image (8), pyramid (8 x 1/7: levels 1 and up), levels
    // (4 / 8). Per radiance voxel: packed accumulators (RADIANCE_FLUX_WORDS x 8, and 8 for red and green
    // in colour), net flux (16), coloured radiance (16); the direct light's edge list (4) and reach bits
    // (1/8 + rows). Per voxel of the objects' boxes: coverage and the voxelize pass's scratch (4 + 4), and
    // its per-axis scratch (12) while it runs. Over the lattice: a field atlas's map.
    const int64_t per_field_voxel = 16 + 8 + 2 + 1;
    const int64_t per_radiance_voxel = (RADIANCE_FLUX_WORDS + 1) * 8 + 16 + 16 + 4 + 1;
    const int64_t per_object_voxel = 4 + 4 + 12;
    const int64_t lattice =
        static_cast<int64_t>(grid.dims.count() / (FIELD_CELL * FIELD_CELL * FIELD_CELL)) * 4;
    // Per floor-map texel: its sums (FLOOR_WORDS words) and the map (8); and for interactive frames' adaptive
    // density the map before the spread (8) and the spread's sums (16).
    const int64_t floor = int64_t{passes::floor_map_texels(grid)} * passes::floor_map_texels(grid) *
                          (4 * FLOOR_WORDS + 8 + 8 + 16);
    const int64_t light_map = int64_t{passes::light_map_capacity(grid)} * passes::light_map_capacity(grid) * 2 * 4;
    // Per pixel: HDR (16), sRGB (4), a slot in the refinement list (4); a still frame's eye rays' ends
    // (RunOptions::still_ends) where they are kept.
    const int64_t pixels = int64_t{width} * height;
    const int64_t per_pixel =
        24 + (static_cast<uint64_t>(pixels) <= kStillEndsMaxPixels ? int64_t{sizeof(shaders::ViewEnd)} : 0);
    return static_cast<int64_t>(field_voxels) * per_field_voxel +
           static_cast<int64_t>(object_voxels) * per_object_voxel +
           static_cast<int64_t>(radiance_voxels) * per_radiance_voxel + lattice + floor + light_map +
           pixels * per_pixel;
}

int64_t estimate_environment_bytes(const image::EnvironmentMap* image) {
    const int64_t texels = image ? int64_t{image->width} * image->height + image->height : 2;
    return texels * static_cast<int64_t>(sizeof(glm::vec4));
}

SceneGpu::SceneGpu(PassKit& kit)
    : kit_(kit), volume_(kit), transport_(kit), view_(kit), recorder_(kit.context, "scene passes"), timer_(kit.context) {}

passes::GridGeometry SceneGpu::lattice_for(PassSet stale, const protocol::SceneDocument& document,
                                           const WorldMeshes& worlds, const FrameInputs::Volume& volume,
                                           const IndexGrid* grid_asset, const Densities& densities) const {
    // Only a rebuilt volume can move the grid: otherwise keep the resident one.
    if (!(stale & kVoxelize) && (built_ & kVoxelize)) return grid_;
    if (!volume.imported) return grid_for(document, worlds, densities);
    if (!grid_asset) throw RenderError("the scene's index field grid is not loaded");
    passes::GridGeometry grid = grid_;
    const auto& b = grid_asset->bounds;
    grid.origin = glm::vec3(static_cast<float>(b.min[0]), static_cast<float>(b.min[1]), static_cast<float>(b.min[2]));
    grid.voxel_size = static_cast<float>((b.max[0] - b.min[0]) / grid_asset->nx);
    grid.dims = {grid_asset->nx, grid_asset->ny, grid_asset->nz};
    return grid;
}

void SceneGpu::gave_way(Pass pass, PassSet stale, PassSet asked, bool keep_mean) {
    // A pass after `pass` that runs only because an earlier one does keeps its output, made before.
    if (!(pass == kPhotons && keep_mean)) built_ = (built_ | (stale & (pass - 1))) & ~((asked | pass) & ~(pass - 1));
}

RunStats SceneGpu::run(PassSet stale, const protocol::SceneDocument& document, const WorldMeshes& worlds,
                       const IndexGrid* grid_asset, const RunOptions& options,
                       const image::EnvironmentMap* environment, const Densities& densities) {
    // The document turned into the stages' inputs; nothing past this block reads it.
    const FrameInputs::Volume volume_in = volume_inputs(document);
    const passes::GridGeometry grid = lattice_for(stale, document, worlds, volume_in, grid_asset, densities);
    // Anything never built, or built for another grid, runs whatever it needs.
    if (!(grid == grid_) || !volume_.has_field()) {
        volume_.clear();
        transport_.clear();
        grid_ = grid;
        built_ = 0;
        stale = kAllPasses;
    }
    // Another radiance-grid resolution, deposit estimator or bounce cap (interactive <-> still) or kind of
    // transport means new photons into a new grid.
    const FrameInputs::Transport photons = photon_settings(document, options);
    if (!transport_.made_for(photons, options)) built_ &= ~(kPhotons | kView | kToneMap);
    transport_.make_for(photons, options);
    const PassSet asked = stale;
    // A refinement step adds a batch to the running mean of those before it. Given way before its first
    // resolve, it leaves that mean in the images, and the frame made from it, as they were (each photon
    // run clears the sums it adds to first): a drag that interrupts it shades from those batches.
    const bool mean_resident = options.photon_batch > 0 && (built_ & kPhotons) &&
                               transport_.photon_batches() == options.photon_batch;
    stale = passes_for(stale) & options.limit;
    view_.allocate({document.image.width, document.image.height});
    if (volume_.lay_out(grid_, volume_in, worlds, stale, built_)) built_ &= ~(kIndexField | kOctree);
    const image::EnvironmentMap* image = document.environment.type == protocol::EnvironmentKind::image ? environment : nullptr;
    transport_.prepare_environment(environment_source(document, image));
    transport_.prepare_medium_field(document.volumes, grid_, densities);
    transport_.prepare(transport_inputs(document, grid_, transport_.environment(),
                                        transport_.medium_emission(), volume_.bending(), options),
                       stale, options, grid_, volume_);

    // One submission for every stale pass (with give_way: one per volume pass and per part of the photons
    // and view, so that the run can stop after any); each pass is bracketed by timestamps.
    FrameRecording recording(recorder_, timer_, options.give_way);
    RunStats stats;
    bool resolved = false;
    const bool whole = volume_.record(recording, stale, built_, volume_in, worlds, grid_asset,
                                      options.voxelize, stats.voxelized) &&
                       transport_.record(recording, stale, built_, options, grid_, volume_, resolved) &&
                       view_.record(recording, stale, options.adaptive_view, view_ends(options),
                                    options.paced_parts, volume_, transport_);
    if (!whole) {
        gave_way(*recording.stopped(), stale, asked, mean_resident && !resolved);
        volume_.end_run();
        stats.gave_way = true;
        return stats;
    }
    // A failure here leaves built_ as it was: the caller drops this scene's state and rebuilds.
    stats.gpu_ms = recording.finish();
    volume_.end_run();
    built_ |= stale;
    stats.ran = stale;
    if (stale & (kPhotons | kView)) {
        shaders::PhotonStats counters{};
        transport_.accumulators().stats.read(&counters, sizeof(counters));
        if (stale & kPhotons) {
            stats.photons_entered = counters.photons_entered;
            stats.photon_steps = counters.steps;
            stats.floor_hits = counters.floor_hits;
            stats.direct_overlaps = counters.direct_overlaps;
            stats.photon_scatterings = counters.scatterings;
        }
        if (stale & kView) stats.view_steps = counters.view_steps;
    }
    return stats;
}

PassSet SceneGpu::passes_for(PassSet stale) const {
    if (!(built_ & kToneMap)) stale |= kToneMap;  // a run leaves a whole frame
    if (stale == 0) return 0;
    // The first stale pass runs with what it reads that is not built, and each pass reruns all after it.
    PassSet first = stale & (~stale + 1);
    while (first != kVoxelize && !(built_ & (first >> 1))) first >>= 1;
    return kAllPasses & ~(first - 1);
}

ViewStage::ParkedFrame SceneGpu::park_view() {
    built_ &= ~(kView | kToneMap);
    return view_.park();
}

void SceneGpu::restore_view(ViewStage::ParkedFrame parked) {
    view_.restore(std::move(parked));
    built_ = (built_ | kView) & ~kToneMap;
}

uint32_t SceneGpu::photon_batches(const protocol::SceneDocument& document, const RunOptions& options) const {
    return (built_ & kPhotons) && transport_.made_for(photon_settings(document, options), options)
               ? transport_.photon_batches()
               : 0u;
}

}  // namespace refract::scene
