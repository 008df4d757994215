#include "render/frame_budget.h"

#include <algorithm>
#include <cmath>

namespace refract::scene {

namespace {

// The least scale that keeps `side` at its floor: kMinScale of it, and kMinSide pixels (or all of it).
double least_scale(uint32_t side) {
    return std::max(static_cast<double>(std::min(side, FrameBudget::kMinSide)) / side, FrameBudget::kMinScale);
}

// `side` at `scale`, which lies between the floors' least scale and 1: one scale for both sides, so that
// a frame shrunk to its floor keeps the document's aspect (a side clamped alone reshaped it).
uint32_t scaled_side(uint32_t side, double scale) {
    return static_cast<uint32_t>(std::clamp(std::round(side * scale), 1.0, static_cast<double>(side)));
}

// A frame's cost is split between the photon pass and the rest; the photon pass may take at most this
// share of the budget, so that a light drag still leaves the image its resolution.
constexpr double kPhotonBudgetShare = 0.5;
// Unless the photons at their floor (kMinPhotonShare, kMinPhotons) take more than their share: their
// pass has a fixed part (the light map, the resolve, the spread: about 30 ms of a 45 ms pass at 4096
// photons on two cores), so the image takes what they leave, down to this share, rather than the frame
// missing its budget.
constexpr double kLeastImageShare = 0.25;
// Aim under the budget: a frame's time varies with the view (more refraction, more steps), and the
// budget is the whole frame's, while this aims its passes: the PNG encode and the frame's delivery
// (8-10 ms at interactive sizes on two cores) come on top.
constexpr double kHeadroom = 0.8;
// How far one frame's measurement may move a cost estimate (a factor), so that one outlier frame (a
// page fault, another scene's work) does not swing the resolution. The first measurement is taken whole.
constexpr double kMaxStep = 1.5;
// Before any measurement: half the document's side.
constexpr double kFirstScale = 0.5;
// Two photon measurements fit the fixed part and the part that scales only where their counts differ by
// at least this factor: a frame's time varies by a few milliseconds, which between near counts would
// make the slope anything.
constexpr double kDistinctShares = 1.5;

// The cost at the document's own size or count that `measured_ms` for `share` of it implies, moved from
// `estimate` by at most kMaxStep.
double corrected(double estimate, double measured_ms, double share) {
    const double implied = measured_ms / share;
    return estimate > 0.0 ? std::clamp(implied, estimate / kMaxStep, estimate * kMaxStep) : implied;
}

}  // namespace

FrameBudget::PhotonKind FrameBudget::photon_kind(const protocol::SceneDocument& document) {
    PhotonKind kind{document.photons.max_bounces, {}};
    for (const auto& [name, volume] : document.volumes) kind.volumes.emplace_back(name, volume.asset);
    return kind;
}

uint32_t FrameBudget::floor_photons(const protocol::SceneDocument& document) {
    const double count = document.photons.count;
    return static_cast<uint32_t>(
        std::min(count, std::max<double>(kMinPhotons, std::round(count * kMinPhotonShare))));
}

InteractiveSettings FrameBudget::choose(const protocol::SceneDocument& document, bool photons_rerun, bool view_rerun,
                                        const InteractiveSettings* resident, double budget_ms) const {
    // What the viewer's size costs comes first; the passes share what is left, and never less than a
    // quarter of the budget.
    const double target = std::max(budget_ms * kHeadroom - viewer_ms_, budget_ms * kHeadroom * 0.25);
    InteractiveSettings settings;
    double photon_ms = 0.0;  // what this frame's photon pass is expected to take
    if (resident && !photons_rerun) {
        settings.photons = resident->photons;
    } else if (last_photon_share_ > 0.0 && !(photon_kind(document) == measured_)) {
        settings.photons = std::min(document.photons.count, kMinPhotons);
        if (document.photons.count > 0)  // the other kind's cost: a guess
            photon_ms = photon_cost(static_cast<double>(settings.photons) / document.photons.count);
    } else {
        double share = kMaxPhotonShare;
        if (last_photon_share_ > 0.0)  // what the photons' half of the budget leaves past their fixed part
            share = photon_ms_ > 0.0 ? std::clamp((kPhotonBudgetShare * target - photon_fixed_ms_) / photon_ms_,
                                                  kMinPhotonShare, kMaxPhotonShare)
                                     : kMaxPhotonShare;
        const double count = document.photons.count;
        settings.photons = static_cast<uint32_t>(std::min(count, std::max<double>(kMinPhotons, std::round(count * share))));
        if (count > 0) photon_ms = photon_cost(settings.photons / count);
    }
    if (resident && !view_rerun) {
        settings.width = resident->width;
        settings.height = resident->height;
    } else {
        // The image's time scales with its pixels, i.e. with the square of the scale; what the photons
        // take of this frame is not the image's to spend.
        const double image_target = std::max(target - photon_ms, kLeastImageShare * target);
        const double wanted = image_ms_ > 0.0 ? std::sqrt(image_target / image_ms_) : kFirstScale;
        const double scale = std::clamp(
            wanted, std::max(least_scale(document.image.width), least_scale(document.image.height)), 1.0);
        settings.width = scaled_side(document.image.width, scale);
        settings.height = scaled_side(document.image.height, scale);
    }
    return settings;
}

void FrameBudget::observe(const protocol::SceneDocument& document, const InteractiveSettings& used, double photon_ms,
                          double viewer_ms, double rest_ms) {
    viewer_ms_ = viewer_ms > 0.0 ? corrected(viewer_ms_, viewer_ms, 1.0) : 0.0;
    if (photon_ms > 0.0 && used.photons > 0 && document.photons.count > 0) {
        PhotonKind kind = photon_kind(document);
        // Another kind's measurement is taken whole, not moved from the last kind's by kMaxStep.
        if (!(kind == measured_)) last_photon_share_ = 0.0;
        fit_photons(static_cast<double>(used.photons) / document.photons.count, photon_ms);
        measured_ = std::move(kind);
    }
    if (rest_ms > 0.0 && used.width > 0 && used.height > 0) {
        const double pixels = static_cast<double>(used.width) * used.height;
        image_ms_ = corrected(image_ms_, rest_ms, pixels / (static_cast<double>(document.image.width) * document.image.height));
    }
}

// The photon model through this measurement (`ms` for `share` of the count): where the last one was at a
// count kDistinctShares apart or more, the larger count the dearer, the line through both (its fixed part
// kept between 0 and `ms`); else both parts moved by the same factor, at most kMaxStep; the first is
// taken for a cost proportional to the count, as nothing yet tells the parts apart.
void FrameBudget::fit_photons(double share, double ms) {
    if (last_photon_share_ <= 0.0) {
        photon_fixed_ms_ = 0.0;
        photon_ms_ = ms / share;
    } else if (const double slope = (ms - last_photon_ms_) / (share - last_photon_share_);
               std::max(share, last_photon_share_) >= kDistinctShares * std::min(share, last_photon_share_) && slope > 0.0) {
        photon_fixed_ms_ = std::clamp(ms - slope * share, 0.0, ms);
        photon_ms_ = (ms - photon_fixed_ms_) / share;
    } else {
        const double factor = std::clamp(ms / photon_cost(share), 1.0 / kMaxStep, kMaxStep);
        photon_fixed_ms_ *= factor;
        photon_ms_ *= factor;
    }
    last_photon_share_ = share;
    last_photon_ms_ = ms;
}

}  // namespace refract::scene
