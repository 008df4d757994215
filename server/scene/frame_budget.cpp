#include "scene/frame_budget.h"

#include <algorithm>
#include <cmath>

namespace refract::scene {

namespace {

uint32_t scaled_side(uint32_t side, double scale) {
    const double floor = std::max(static_cast<double>(std::min(side, FrameBudget::kMinSide)),
                                  std::ceil(side * FrameBudget::kMinScale));
    return static_cast<uint32_t>(std::clamp(std::round(side * scale), floor, static_cast<double>(side)));
}

// A frame's cost is split between the photon pass and the rest; the photon pass may take at most this
// share of the budget, so that a light drag still leaves the image its resolution.
constexpr double kPhotonBudgetShare = 0.5;
// Aim under the budget: a frame's time varies with the view (more refraction, more steps), and the
// budget is the whole frame's, while this aims its passes: the PNG encode and the frame's delivery
// (8-10 ms at interactive sizes on two cores) come on top.
constexpr double kHeadroom = 0.8;
// How far one frame's measurement may move the scale or the photon share (a factor), so that one
// outlier frame (a page fault, another scene's work) does not swing the resolution.
constexpr double kMaxStep = 1.5;

}  // namespace

InteractiveSettings FrameBudget::choose(const protocol::SceneDocument& document, bool photons_rerun, bool view_rerun,
                                        const InteractiveSettings* resident) const {
    InteractiveSettings settings;
    if (resident && !view_rerun) {
        settings.width = resident->width;
        settings.height = resident->height;
    } else {
        settings.width = scaled_side(document.image.width, scale_);
        settings.height = scaled_side(document.image.height, scale_);
    }
    if (resident && !photons_rerun) {
        settings.photons = resident->photons;
    } else {
        const double count = document.photons.count;
        settings.photons = static_cast<uint32_t>(
            std::min(count, std::max<double>(kMinPhotons, std::round(count * photon_share_))));
    }
    return settings;
}

void FrameBudget::observe(const protocol::SceneDocument& document, const InteractiveSettings& used, double photon_ms,
                          double rest_ms, double budget_ms) {
    const double target = budget_ms * kHeadroom;
    if (photon_ms > 0.0 && document.photons.count > 0) {
        const double share_used = static_cast<double>(used.photons) / document.photons.count;
        const double factor = std::clamp(kPhotonBudgetShare * target / photon_ms, 1.0 / kMaxStep, kMaxStep);
        photon_share_ = std::clamp(share_used * factor, kMinPhotonShare, kMaxPhotonShare);
    }
    if (rest_ms > 0.0) {
        // The photons' share of this frame is not the image's to spend; the image's time scales with its
        // pixels, i.e. with the square of the scale.
        const double image_target = std::max(target - photon_ms, (1.0 - kPhotonBudgetShare) * target);
        const double scale_used = static_cast<double>(used.width) / document.image.width;
        const double factor = std::clamp(std::sqrt(image_target / rest_ms), 1.0 / kMaxStep, kMaxStep);
        scale_ = std::clamp(scale_used * factor, kMinScale, 1.0);
    }
}

}  // namespace refract::scene
