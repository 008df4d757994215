// One scene's resident GPU state (index field, octree, radiance grid, floor caustic map, frame buffers)
// and the recording of its stale passes into one submission. The renderer owns one per resident scene;
// tests and the CLI use it directly to read intermediate volumes back.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "assets/index_grid.h"
#include "image/environment_map.h"
#include "mesh/mesh.h"
#include "passes/grid_geometry.h"
#include "protocol/scene_document.h"
#include "render/field_atlas.h"
#include "render/frame_inputs.h"
#include "render/invalidation.h"
#include "render/object_mesh.h"
#include "render/pass_kit.h"
#include "render/transport_stage.h"
#include "render/view_stage.h"
#include "render/volume_stage.h"
#include "fresnel.h"
#include "transport.h"

namespace refract::scene {

// What one run of the stale passes measured.
struct RunStats {
    PassSet ran = 0;  // the passes that ran: those asked for, plus what they found stale
    std::vector<std::pair<std::string, double>> gpu_ms;  // per pass that ran
    uint64_t photons_entered = 0;
    uint64_t photon_steps = 0;
    uint64_t floor_hits = 0;
    uint64_t direct_overlaps = 0;  // photons the light map sent straight where n varies (transport.h)
    uint64_t photon_scatterings = 0;  // scattering events of the photons' random walks
    uint64_t view_steps = 0;  // eye-ray march steps, when the viewing pass ran
    std::vector<std::string> voxelized;  // the objects the voxelize pass ran for, by name
    bool gave_way = false;  // the run stopped at a part (RunOptions::give_way): no frame came of it
    double mean_steps_per_photon() const {
        return photons_entered ? static_cast<double>(photon_steps) / static_cast<double>(photons_entered) : 0.0;
    }
    double mean_bounces_per_photon() const {
        return photons_entered ? static_cast<double>(photon_scatterings) / static_cast<double>(photons_entered) : 0.0;
    }
};

// The most pixels a still frame keeps its eye rays' ends for (RunOptions::still_ends): 48 bytes each,
// 96 MiB at this many (1920 x 1080 fits).
inline constexpr uint64_t kStillEndsMaxPixels = uint64_t{1} << 21;

struct RunOptions {
    bool fixed_step = false;      // photons step one voxel everywhere (reference for the octree's gain)
    bool record_photon_exits = false;
    // Each light traces photons only along the rays that may meet an object (emit_photon_ray), where the
    // direct light's closed form takes the others' light whole; false: over its whole emitter (the
    // reference for that estimate; also whenever photon exits are recorded).
    bool photon_part = true;
    PassSet limit = kAllPasses;   // passes outside this set are not run (the CLI's voxelize and trace)
    // The voxelize pass keeps each object's resident coverage while its world mesh, box, smoothing and
    // rays stay (voxelize.again: every object anew).
    VoxelizeOptions voxelize;
    float view_step = 1.0f;  // eye-ray step in scattering media (voxels); interactive frames use 2
                             // (at least radiance_factor: transport_inputs, frame_inputs.cpp)
    // The view step of reflected eye paths, in view steps (FRESNEL_REFLECTED_VIEW_STEP; 1: as the first).
    float reflected_view_step = FRESNEL_REFLECTED_VIEW_STEP;
    // A reflected eye path whose share of the pixel's light is below this in every channel takes the floor
    // or sky straight instead of being marched (FRESNEL_EYE_TRACED_SHARE; interactive frames take every
    // reflection straight: FRESNEL_PREVIEW_TRACED_SHARE).
    float traced_reflection_share = FRESNEL_EYE_TRACED_SHARE;
    uint32_t radiance_factor = 1; // scene voxels (passes::GridGeometry::light_factor lattice voxels each) per
                                  // radiance-grid voxel per axis; interactive: 3
    bool sampled_deposits = false; // photons deposit once per radiance voxel of path, not exactly per
                                   // voxel crossed (photon_trace.comp); every frame run_options_for makes
                                   // (the exact estimator is the physics tests' reference)
    bool adaptive_view = false;   // trace a quarter of the pixels, then only where they differ; interactive
    // Eye paths that bent filter the floor they reach over where the neighbouring pixels' rays land
    // (view.comp, neighbour_footprint); false: over the straight cone (interactive: an adaptive frame's
    // traced pixels must be the bytes of a frame that traced them all, and its second round's neighbours
    // are not its own).
    bool neighbour_footprints = true;
    // The viewing pass also keeps where its eye rays end, so that the frame can be brought to a larger
    // viewer's size (SceneGpu::upscale): interactive frames traced smaller than their viewer.
    bool view_ends = false;
    // A still frame's first sample also keeps where its eye rays end, at its own size, for the light drags
    // after it (ViewStage::Ends::still): their frames, traced smaller, take each viewer pixel's own eye
    // ray from it while nothing but the light changes (SceneGpu::upscale).
    bool still_ends = false;
    // Each radiance voxel's light spread over a box sized by the photons behind it (radiance_spread.comp):
    // smooth where photons are few; interactive.
    bool adaptive_density = false;
    bool direct_light = true;     // unbent light in closed form; false: photons carry all light (tests)
    uint32_t bounce_cap = protocol::kMaxBounces;  // most of photons.max_bounces a frame takes; interactive: 4
    // Progressive refinement (still frames): a photon run with photon_batch k > 0 draws new photons and
    // joins the radiance grid's running mean of k + 1 batches; a view run with view_sample s > 0 traces
    // a jittered sample into the frame's running mean of s + 1 samples. Runs must come in order.
    uint32_t photon_batch = 0;
    uint32_t view_sample = 0;
    // Temporal reuse (render/temporal_history.h): an interactive frame's one eye-ray sample per pixel at
    // the sub-pixel offset of view sample `view_jitter` (0: the centre), so successive frames sample
    // different points.
    uint32_t view_jitter = 0;
    // Interactive light drags: the share of the radiance grid's light its previous frames keep (their
    // photons, weighted by age as an exponential moving average; 0: the new photons replace them), and
    // which frame of such a run this is (each draws photons of its own seed).
    float photon_history = 0.0f;
    uint32_t history_frame = 0;
    // Set (the render queue sets it for every frame): the photon and view dispatches then run in parts of
    // at most passes::kWorkPart photons or kViewPart pixels (about passes::kPartMs each: passes::PartPacer),
    // a submission each, and this is asked after each; when it says to stop, the run stops there
    // (RunStats::gave_way), and what its photon and view passes hold is partial: built() leaves out the
    // pass it stopped in and those asked for after it (the renderer keeps the refinement level before the
    // step only where its view is left whole).
    std::function<bool()> give_way;
    bool paced_parts = true;  // FrameOptions::paced_parts
};

// Device memory a scene holds (bytes), for budgets before allocating: its lattice `grid`, the field's
// voxels (field_atlas: the lattice's for a scene of one object), objects' boxes of `object_voxels` in
// all, the radiance grid's voxels and the frame.
int64_t estimate_scene_bytes(const passes::GridGeometry& grid, uint64_t field_voxels, uint64_t object_voxels,
                             uint64_t radiance_voxels, uint32_t width, uint32_t height);

// Device memory an image environment's map and its sampling rows take (passes/environment_light.h);
// `image` nullptr for a uniform environment or the sky (a placeholder of a few texels).
int64_t estimate_environment_bytes(const image::EnvironmentMap* image);

class SceneGpu {
public:
    explicit SceneGpu(PassKit& kit);

    // Runs `stale` passes for `document`, with what passes_for() adds to them.
    // `worlds` holds every object's mesh in world space, read only when the voxelize pass runs: the
    // lattice is fitted to them (an edit that moves the lattice makes voxelize stale), and the pass
    // voxelizes only the objects whose world mesh, box or smoothing changed since their coverage was
    // made (all of them when the lattice moved); imported grids have none. `grid_asset` is the imported
    // index grid for index_field == grid; `environment` the map an image environment names: a changed
    // map must come as a new pointer (the resident copy is kept while the pointer and the document's
    // environment stay). The document is turned into each stage's inputs (FrameInputs) at the top; the
    // stages record into one recording, in parts when the run may give way. `densities` holds the grid of
    // each of the document's volumes (a changed grid must come as a new pointer). Throws vk::Error on
    // device failures, RenderError for a volume without its grid.
    RunStats run(PassSet stale, const protocol::SceneDocument& document, const WorldMeshes& worlds,
                 const IndexGrid* grid_asset, const RunOptions& options = {},
                 const image::EnvironmentMap* environment = nullptr, const Densities& densities = {});

    const passes::GridGeometry& grid() const { return grid_; }
    const FieldAtlas& field_atlas() const { return volume_.atlas(); }
    // The passes whose results are resident and whole.
    PassSet built() const { return built_; }
    // The passes a run asked for `stale` runs (before RunOptions::limit, on this grid and radiance grid):
    // those, what the first of them reads that is not built, every pass after them, and the whole frame
    // when it is not built.
    PassSet passes_for(PassSet stale) const;
    // Whole photon batches (RunOptions::photon_batch) in the resident radiance grid that a run with
    // `options` over `document` would shade from rather than trace anew: 0 when there are none, or the
    // grid was made with other photon settings (radiance factor, deposits, bounces, kind of transport).
    uint32_t photon_batches(const protocol::SceneDocument& document, const RunOptions& options) const;
    // `options` with the photon settings the resident radiance grid was made with, so that a run that
    // needs no photons shades from that grid, whatever quality made it.
    RunOptions with_resident_photons(RunOptions options) const { return transport_.with_resident_photons(options); }
    uint32_t width() const { return view_.width(); }
    uint32_t height() const { return view_.height(); }
    // The still frame of one view put aside while another renders, and put back (ViewStage::ParkedFrame):
    // parked, the view and tone map are no longer built; restored, the view is, its tone map not.
    ViewStage::ParkedFrame park_view();
    void restore_view(ViewStage::ParkedFrame parked);

    // Read-backs (each a separate submission): float per voxel / texel, x fastest. The field's (coverage,
    // objects, index field, levels) are per voxel of the lattice, what the transport's lookups see there
    // (the medium's outside a field atlas's clusters); the pyramid is the field images' own.
    std::vector<float> read_coverage() const { return volume_.read_coverage(); }
    // Per voxel: 1 + the number of the object it holds, 0: none.
    std::vector<uint32_t> read_object_numbers() const { return volume_.read_object_numbers(); }
    std::vector<glm::vec4> read_index_field() const { return volume_.read_index_field(); }
    std::vector<uint32_t> read_levels() const { return volume_.read_levels(); }  // octree leaf level per voxel
    // Octree (min, max) n per node, levels 1 and up back to back.
    std::vector<glm::vec2> read_pyramid() const { return volume_.read_pyramid(); }
    std::vector<glm::vec4> read_radiance() const { return transport_.read_radiance(); }  // fluence rate rgb (W/m^2)
    // Net flux vector xyz, fluence rate w (channel mean; W/m^2).
    std::vector<glm::vec4> read_flux() const { return transport_.read_flux(); }
    uint32_t channels() const { return transport_.channels(); }  // how the photons last ran carried colour (CHANNELS_*)
    bool grey() const { return transport_.grey(); }              // one fluence for all channels (transport.h)
    // The change of floor irradiance the grid causes (W/m^2, signed), floor_map_side()^2 texels.
    std::vector<glm::vec4> read_floor_map() const { return transport_.read_floor_map(); }
    // Total floor irradiance at the floor map's texel centres, as the viewing pass shades it: the
    // unobstructed light plus the map's change, clamped at zero.
    std::vector<glm::vec4> read_floor_irradiance() const { return transport_.read_floor_irradiance(); }
    std::vector<glm::vec4> read_hdr() const { return view_.read_hdr(); }
    const vk::Buffer& hdr_buffer() const { return view_.hdr(); }  // what temporal reuse takes in
    std::vector<uint32_t> read_ldr() const { return view_.read_ldr(); }
    // An interactive frame traced smaller than its viewer, brought to the viewer's size (ViewStage::upscale):
    // possible once a run with RunOptions::view_ends left the frame's eye rays' ends.
    bool has_view_ends() const { return view_.has_ends(); }
    // Whether a still frame's eye rays' ends are kept for a viewer of this size (RunOptions::still_ends).
    bool has_still_ends(uint32_t width, uint32_t height) const { return view_.has_still_ends(width, height); }
    // `still_ends`: the caller knows the still frame that kept them saw the same eye rays (has_still_ends).
    void upscale(uint32_t width, uint32_t height, bool still_ends = false) {
        view_.upscale(width, height, still_ends, volume_, transport_);
    }
    std::vector<glm::vec4> read_viewer_hdr() const { return view_.read_viewer_hdr(); }
    std::vector<uint32_t> read_viewer_ldr() const { return view_.read_viewer_ldr(); }
    int64_t upscale_bytes() const { return view_.upscale_bytes(); }
    std::vector<shaders::PhotonExit> read_photon_exits() const { return transport_.read_photon_exits(); }
    // The last run's parameters: the first light's (which the viewing pass reads), and every light's.
    const shaders::TransportParams& params() const { return transport_.light_params().front(); }
    const std::vector<shaders::TransportParams>& light_params() const { return transport_.light_params(); }
    uint32_t floor_map_side() const { return transport_.floor_map_side(); }

private:
    // The lattice the run builds on: the resident one, unless the volume is rebuilt (then fitted to the
    // document's objects, or the imported grid's).
    passes::GridGeometry lattice_for(PassSet stale, const protocol::SceneDocument& document, const WorldMeshes& worlds,
                                     const FrameInputs::Volume& volume, const IndexGrid* grid_asset,
                                     const Densities& densities) const;
    // What the run holds when it stopped in `pass`: the passes before it built, it and those asked for
    // after it not (`keep_mean`: a photon pass stopped before touching the running mean keeps it).
    void gave_way(Pass pass, PassSet stale, PassSet asked, bool keep_mean);

    PassKit& kit_;
    passes::GridGeometry grid_{};
    PassSet built_ = 0;
    VolumeStage volume_;
    TransportStage transport_;
    ViewStage view_;
    vk::CommandRecorder recorder_;
    vk::GpuTimer timer_;
};

}  // namespace refract::scene
