// Layout shared by the temporal reuse pass (shaders/temporal_reuse.comp) and its host code
// (server/passes/temporal_reuse.*): a viewer's full-resolution history of what it was shown, into which
// each interactive frame's jittered samples are reprojected and blended (TEMPORAL.md).
#ifndef REFRACT_SHADERS_TEMPORAL_H
#define REFRACT_SHADERS_TEMPORAL_H

#include "shared_types.h"

#define TEMPORAL_GROUP_SIZE 8  // 8x8 history pixels per group
#define TEMPORAL_BINDING_PARAMS 0
#define TEMPORAL_BINDING_SAMPLES 1      // vec4 per sample-frame pixel: linear radiance rgb, w inverse depth (1/m)
#define TEMPORAL_BINDING_HISTORY_IN 2   // vec4 per history pixel: radiance rgb, w the samples it stands on
#define TEMPORAL_BINDING_DEPTH_IN 3     // float per history pixel: inverse depth (1/m; 0: the sky)
#define TEMPORAL_BINDING_HISTORY_OUT 4
#define TEMPORAL_BINDING_DEPTH_OUT 5
#define TEMPORAL_BINDING_LDR 6          // uint per history pixel: tone-mapped sRGB RGBA8
// Two vec4 per sample: the mean and the standard deviation of the radiance of its 3x3 neighbourhood
// (temporal_neighbourhood.comp), which bound what the history may hold where anything moved.
#define TEMPORAL_BINDING_NEIGHBOURHOOD 7
// The history is clipped to the neighbourhood's mean +- this many standard deviations (variance
// clipping: a box that follows the samples smoothly, where a min-max box of the nearest sample's
// neighbourhood would be constant over each sample's footprint and show it as blocks).
#define TEMPORAL_CLIP_DEVIATIONS 1.25

REFRACT_SHADERS_BEGIN

// A pinhole camera as the viewing pass builds its rays (view.comp, shade).
struct TemporalCamera {
    vec4 position;  // xyz: the eye (world), w: tan(fov / 2)
    vec4 forward;
    vec4 right;
    vec4 up;
};

struct TemporalParams {
    TemporalCamera now;     // the camera of the samples
    TemporalCamera before;  // the camera the history was made with
    uvec4 sizes;            // xy: the history's pixels (the viewer's), zw: the sample frame's
    vec4 jitter;            // xy: the samples' offset from their pixels' centres (sample pixels); z: exposure multiplier
    // x: a sample's weight in the history pixel it falls in (0: the history is only re-toned), y: the
    // weight of the samples' bilinear estimate in a pixel none falls in, z: the most samples a history
    // pixel counts (fewer while the camera moves, so it follows), w: 1 = history clamped to the samples'
    // neighbourhood (something moved), 0 = trusted as it is (nothing did).
    vec4 blend;
    uvec4 state;            // x: 1 = the history holds a frame, y: 1 = the camera moved since it
};

REFRACT_SHADERS_END

#ifdef __cplusplus
static_assert(sizeof(refract::shaders::TemporalParams) == 8 * 16 + 4 * 16);
#endif

#endif
