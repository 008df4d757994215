// The renderer: owns every scene's resident GPU state (index field, octree, radiance grid) and runs the
// paper's passes on the one Vulkan queue, rerunning only the passes an edit made stale.
// Thread-compatible: exactly one thread (the daemon's render thread, or the CLI) calls it.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "assets/assets.h"
#include "assets/render_error.h"
#include "protocol/scene_document.h"
#include "render/frame_budget.h"
#include "render/invalidation.h"
#include "render/scene_gpu.h"

namespace refract::mesh {
struct Mesh;
}
namespace refract::image {
struct EnvironmentMap;
}
namespace refract::vk {
class Context;
}

namespace refract::scene {

enum class Quality { interactive, still };

// Scattering events per photon the photons of interactive frames take at most: each bounce costs about
// one more free path of steps, and the first few carry most of the glow (docs/multiple-scattering.md).
inline constexpr uint32_t kInteractiveBounces = 4;
// The share of the radiance grid's light a light drag's frame keeps from the frames before it, while the
// light has moved less than a radiance voxel (RunOptions::photon_history): the last frame's photons
// weigh a half, the one before a quarter, and so on.
inline constexpr float kPhotonHistory = 0.5f;

// How the passes run for a quality: `interactive` takes two-voxel eye-ray steps in fog, a radiance
// grid of a third of the resolution per axis, sampled photon deposits, adaptive pixels and at most
// kInteractiveBounces (the image size and photon count are chosen per frame by the scene's FrameBudget,
// in the renderer). An interactive frame whose edit leaves the photons valid keeps the resident grid
// instead, a still frame's too (Renderer::render).
RunOptions run_options_for(Quality quality);

struct PassTiming {
    std::string name;  // "voxelize", "octree", "photons", "view", "encode"
    double gpu_ms = 0.0;
    double host_ms = 0.0;
};

// Progressive refinement of still frames: level 1 is the document's frame; each level after it adds a
// batch of the document's photon count with a new seed to the radiance grid's running mean, until
// kMaxPhotonBatches are in, then an eye-ray sample per pixel at a new sub-pixel offset (anti-aliasing),
// until kMaxViewSamples. The same scene, seed and level give the same bytes however the level was reached.
constexpr uint32_t kMaxPhotonBatches = 16;
constexpr uint32_t kMaxViewSamples = 16;
constexpr uint32_t kMaxRefinementLevel = kMaxPhotonBatches + kMaxViewSamples - 1;

struct Refinement {
    uint32_t photon_batches = 1;
    uint32_t samples_per_pixel = 1;
};
// What a refinement level holds (levels past kMaxRefinementLevel hold what it does).
Refinement refinement_at(uint32_t level);

// How a frame is rendered, beyond its document.
struct FrameOptions {
    Quality quality = Quality::still;
    double budget_ms = kDefaultBudgetMs;  // interactive frames: the frame-time budget (frame_budget.h)
    uint32_t level = 1;                   // still frames: the refinement level, 1 to kMaxRefinementLevel
    // When set, each step of a frame (level 1, and each refinement level past it) asks it between the parts
    // of its photon and view dispatches (RunOptions::give_way), and stops (Outcome::superseded) if it says so: the
    // render queue sets it for every frame (it renders other scenes' frames there, and stops a frame
    // nobody waits for), and a refinement level gives way to its viewer's next edit, which then waits for
    // one part (at most passes::kWorkPart photons or kViewPart pixels, about passes::kPartMs), not a whole
    // frame. The step's refinement state is then dropped, so levels stay the same bytes however reached.
    std::function<bool()> give_way;
    // Parts sized by time (passes::PartPacer, about kPartMs); false: every part the largest, so the parts
    // and the chances to give way between them are the same on every run (a test that counts them).
    bool paced_parts = true;
    // Still frames: when above `level`, the frame may hold any level up to this one, and holds the highest
    // that the resident state already gives for no more work than `level` (the batches its radiance grid
    // holds, or the refined frame an exposure edit re-tones). The still after a camera drag then shows
    // the grid that drag was shaded from instead of rerunning the photons of level 1. 0: exactly `level`.
    uint32_t resume_up_to = 0;
    // Also read back the frame's linear radiance (FrameResult::linear), for an OpenEXR answer.
    bool linear = false;
    // Interactive frames: the viewer (a WebSocket session) whose temporal history (render/temporal_history.h)
    // takes the frame in; the frame is then that history at the document's image size. Empty: none, the
    // frame traced at the budget's size is upscaled to the document's (passes::ViewUpscalePass).
    std::string history;
};

struct FrameResult {
    // Ordinary ends besides a frame, which a caller that lets frames give way must expect:
    // superseded: the frame gave way to waiting work (FrameOptions::give_way) and none came of it;
    // deferred: asked for between the parts of another scene's frame, it would fit the memory budget
    // only by evicting that scene, so it waits for that frame to end.
    enum class Outcome { made, superseded, deferred };
    Outcome outcome = Outcome::made;
    std::vector<uint8_t> png;
    std::vector<glm::vec4> linear;  // RGBA radiance before exposure, top row first; FrameOptions::linear only
    uint32_t width = 0, height = 0;
    // The size its eye rays were traced at: an interactive frame's budget may trace fewer pixels than it
    // is sent at (its floor and sky are found again at `width` x `height`: passes::ViewUpscalePass).
    uint32_t traced_width = 0, traced_height = 0;
    // Traced smaller, its viewer pixels' own eye rays were a still frame's of the same view (nothing but
    // the light changed since): its outline and what its glass shows are at the viewer's size.
    bool still_eye_rays = false;
    PassSet rerun = 0;                // passes that ran for this frame
    std::vector<std::string> voxelized;  // the objects the voxelize pass ran for, by name
    std::vector<PassTiming> timings;  // one entry per pass that ran, plus "encode"
    uint64_t photons_traced = 0;  // by the photon runs of this frame
    double mean_steps_per_photon = 0.0;
    uint32_t level = 1;           // the refinement level the frame holds (1 for interactive frames)
    Refinement refinement;        // photon batches and samples per pixel in the frame
    uint64_t photons = 0;         // photons in the radiance grid the frame was shaded from, all batches
};

struct RendererOptions {
    size_t max_resident_scenes = 8;     // least recently used scene's GPU state is dropped past this
    int64_t device_memory_budget = 0;  // bytes; 0 = no budget beyond the device's own
};

class Renderer {
public:
    Renderer(vk::Context& context, RendererOptions options = {});
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    // Renders `document` for scene `scene_id`, reusing whatever resident state is still valid for it.
    // May be called again from `options.give_way` for another scene (the render queue renders other
    // scenes' frames between the parts of one): a scene whose frame is in progress is never evicted for
    // it, and a frame that would need that comes back deferred. Time spent in give_way is not the frame's.
    // Interactive frames choose their image size and photon count to land within `options.budget_ms`
    // (frame_budget.h), and shade from the resident radiance grid, whatever quality made it, when their
    // edit leaves its photons valid; still frames render the document as it is, refined to `options.level`.
    // Throws RenderError for an unrenderable scene (resident state untouched), vk::Error for device faults.
    FrameResult render(const std::string& scene_id, const protocol::SceneDocument& document, const Assets& assets,
                       const FrameOptions& options = {});
    // Creates the pipelines that frames of `document` use at `quality`: they are compiled on first use
    // (LLVM on lavapipe: 0.2-0.3 s for a scene's set), which would otherwise fall on its first frame.
    // Renders a reduced copy of `document` (the smallest image, volume and photon count) under a scene id
    // of its own (an interactive one also upscaled, as a drag's frames are; a still one followed by the
    // frame of a light drag after it), keeps nothing of it but the pipelines, and rethrows what render()
    // throws.
    void warm_up(const protocol::SceneDocument& document, const Assets& assets, Quality quality);
    // Creates the pipelines of the first preview a viewer sees on loading `loaded` into a resident scene
    // that shows `before` (an example picked, a document imported): that preview builds the volume on a
    // coarser lattice than a scene's first frame does (kLoadLatticeDivisor, or kDragLatticeDivisor where
    // the objects keep their names), and lavapipe compiles a shader again for the state of the images it
    // samples (0.5-1.5 s of a load on two cores). Renders
    // `before`, then `loaded` at its own volume resolution, both at the smallest image and photon count,
    // under a scene id of its own, keeps nothing of them but the pipelines, and rethrows what render() throws.
    void warm_up_load(const protocol::SceneDocument& before, const protocol::SceneDocument& loaded, const Assets& assets);
    // Builds the resident volume (voxelize, index field, octree) of `document` as scene `scene_id`, and
    // the photons of its first interactive frame, before anyone asks for a frame of it (the daemon's
    // warm-up: those passes are most of a first frame), so that its first interactive frame runs only
    // the view and tone map. One pass a submission; stops before a pass when `stop` says so (the frame
    // then runs the rest). Does nothing and returns false when the scene is
    // resident already or would not fit the resident-scene count or memory budget without evicting
    // another. Throws what render() throws (RenderError for an unrenderable document, state untouched).
    bool prepare(const std::string& scene_id, const protocol::SceneDocument& document, const Assets& assets,
                 const std::function<bool()>& stop);
    // Drops a scene's GPU state (its document lives elsewhere).
    void evict(const std::string& scene_id);
    size_t resident_scenes() const;
    int64_t device_bytes() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace refract::scene
