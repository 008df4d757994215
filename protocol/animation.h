// Keyframed animation of a scene document: merge patches at times, and the document between them.
// Protocol only (no GPU): the CLI's `animate` and the WebSocket `play` message both go through it.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/scene_document.h"

namespace refract::protocol {

// Bounds on what one animation may ask for.
constexpr size_t kMaxKeyframes = 10000;
constexpr double kMaxAnimationSeconds = 86400.0;

class Animation {
public:
    // `keyframes` is a JSON list of {"time": seconds, "patch": merge patch}: times from 0 to
    // kMaxAnimationSeconds, strictly increasing; each patch applies to the document of the keyframe
    // before it (the first to `base`). Throws ValidationError whose pointer points into the list
    // (e.g. /2/patch/object/ior for a patch that makes an invalid document). Keeps the patches and at
    // most kMaxCheckpoints documents, so its memory follows the message, not keyframes x scene size.
    // `keep_going`, when given, is asked every few keyframes; false ends the check (ValidationError at
    // the keyframe reached): checking 10,000 keyframes over a large scene takes seconds.
    Animation(const SceneDocument& base, const nlohmann::json& keyframes, const Limits& limits = {},
              const std::function<bool()>& keep_going = {});

    // The last keyframe's time: the animation runs from 0 to it.
    double duration() const { return times_.back(); }
    size_t keyframes() const { return times_.size(); }

    // The document at time t (seconds): before the first keyframe and after the last, that keyframe's;
    // between two, every number interpolated linearly, except that an object's rotation turns along the
    // shortest arc between the two orientations (spherical) unless only one of its angles changes (a
    // turntable turn keeps every degree asked for, 0 to 720 turns twice), and a light's direction turns
    // at a constant rate; whole numbers (image size, photon count, resolution), names and switches keep
    // the earlier keyframe's value until the next keyframe. Keyframe documents are made as they are
    // reached: playing forward costs one patch per keyframe passed; a jump starts from the checkpoint
    // before it. Not const: it remembers where it is.
    SceneDocument at(double t);

    static constexpr size_t kMaxCheckpoints = 64;

private:
    // Keyframe i's document.
    const SceneDocument& document(size_t i);

    std::vector<double> times_;
    std::vector<nlohmann::json> patches_;
    size_t stride_ = 1;                     // keyframes between two checkpoints
    std::vector<SceneDocument> checkpoints_;  // keyframe k * stride_'s document
    size_t current_ = 0;                    // the keyframe whose document `current_document_` is
    SceneDocument current_document_;
    // The last pair of keyframes interpolated between (to_json of each): frames between two keyframes
    // reuse them.
    size_t pair_ = static_cast<size_t>(-1);
    nlohmann::json pair_from_, pair_to_;
    Limits limits_;
};

}  // namespace refract::protocol
