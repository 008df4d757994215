// Dynamic resolution for interactive frames: while a user drags, each frame's image size (and, when its
// photons rerun anyway, their count) is chosen from what the scene's last interactive frames cost on
// this device, so that a frame lands within a budget. A feedback controller, as game engines run
// dynamic resolution: the model is only "time scales with pixels, and with photons past a fixed part",
// each frame's measurement corrects it, and the next frame is sized for the passes it will run (a light
// drag's frames share the budget with the photon pass, a camera drag's give it all to the image).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "protocol/scene_document.h"

namespace refract::scene {

constexpr double kDefaultBudgetMs = 100.0;
constexpr double kMinBudgetMs = 10.0;
constexpr double kMaxBudgetMs = 10000.0;
// While an object is dragged the lattice has half the voxels per axis (InteractiveSettings).
constexpr uint32_t kDragLatticeDivisor = 2;
// The first frame of other objects (a scene loaded or imported, every object built at once), a quarter.
constexpr uint32_t kLoadLatticeDivisor = 4;

// What an interactive frame renders, against the document's own still frame.
struct InteractiveSettings {
    uint32_t width = 0, height = 0;  // image size
    uint32_t photons = 0;            // photon count
    // The lattice's voxels per axis divided by this: 2 while an object moves (its volume rebuilt every
    // frame at an eighth of the voxels), 4 from a frame of other objects until a still frame, else 1, the
    // document's own lattice.
    uint32_t lattice_divisor = 1;
};

class FrameBudget {
public:
    // The floor on resolution: an image side never shrinks below this fraction of the document's (nor
    // below kMinSide pixels, nor above the document's own), so the budget never starves the image; both
    // sides take one scale, so a frame keeps the document's aspect.
    static constexpr double kMinScale = 0.125;
    static constexpr uint32_t kMinSide = 32;
    // Photons per interactive frame, as a fraction of the document's count: at most a quarter (the
    // pre-budget interactive setting), at least 1/64 and never fewer than kMinPhotons; kMinPhotons for
    // photons of another kind than those measured (PhotonKind), until they are measured.
    static constexpr double kMaxPhotonShare = 0.25;
    static constexpr double kMinPhotonShare = 1.0 / 64.0;
    static constexpr uint32_t kMinPhotons = 4096;

    // The fewest photons an interactive frame of `document` traces: kMinPhotonShare of its count, not
    // below kMinPhotons (nor above its count).
    static uint32_t floor_photons(const protocol::SceneDocument& document);

    // The settings for the next interactive frame of `document`, to land within `budget_ms`.
    // `photons_rerun`: the edit reruns the photon pass anyway, so its count may change (otherwise the
    // resident count must be kept, or a camera drag would retrace photons). `resident`: the settings the
    // resident state was rendered with, kept where changing them would rerun a pass the edit does not need.
    InteractiveSettings choose(const protocol::SceneDocument& document, bool photons_rerun, bool view_rerun,
                               const InteractiveSettings* resident, double budget_ms) const;

    // What a photon's cost depends on beyond the document's sizes: how it may scatter (its random walks,
    // the volumes it crosses, by name and asset). A photon cost measured for one kind says nothing of
    // another's (the cumulus example's photons, up to four bounces in a dense cloud, took 0.7 s for a
    // sixty-fourth of its count, loaded after one whose photons took 35 ms).
    struct PhotonKind {
        uint32_t max_bounces = 0;
        std::vector<std::pair<std::string, std::string>> volumes;
        bool operator==(const PhotonKind&) const = default;
    };
    static PhotonKind photon_kind(const protocol::SceneDocument& document);

    // Feeds back what a frame rendered with `used` cost: milliseconds in the photon pass (0 when it did
    // not run), what the viewer's full size costs whatever size was traced (`viewer_ms`: temporal reuse
    // and the encode of its frame, render/temporal_history.h; 0 without), and everything else (view,
    // tone map, read-back, encode).
    void observe(const protocol::SceneDocument& document, const InteractiveSettings& used, double photon_ms,
                 double viewer_ms, double rest_ms);

private:
    // What a frame would cost at the document's own image size and photon count, as the last frames
    // measured it (0: not yet measured). Kept per pass rather than as a scale, so that the first frame
    // of a light drag after a camera drag (or the other way round) is sized for the passes it runs.
    double image_ms_ = 0.0;   // everything but the photon pass
    double viewer_ms_ = 0.0;  // the frame's fixed part at the viewer's size, taken off the budget first
    // The photon pass as a fixed part (the light map, the resolve, the spread: the lattice's, whatever
    // the count) plus a part that scales with the count, fitted through the last two measurements whose
    // counts differ enough (fit_photons): a frame at the floor's 4096 photons costs most of what one at
    // 2^16 does, which a cost proportional to the count took for a sixteenth.
    double photon_fixed_ms_ = 0.0;
    double photon_ms_ = 0.0;          // the part that scales, at the document's own count
    double last_photon_share_ = 0.0;  // the last measurement's share of the count (0: none yet)
    double last_photon_ms_ = 0.0;     // and what it took
    PhotonKind measured_;             // of the photons measured: other kinds' frames take kMinPhotons

    double photon_cost(double share) const { return photon_fixed_ms_ + photon_ms_ * share; }
    void fit_photons(double share, double ms);
};

}  // namespace refract::scene
