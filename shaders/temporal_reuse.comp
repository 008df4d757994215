#version 460
#extension GL_GOOGLE_include_directive : require
// Temporal reuse (TEMPORAL.md): one thread per pixel of a viewer's full-resolution history. An
// interactive frame traces fewer pixels than the viewer shows, each at a jittered point of its pixel, so
// successive frames sample different points. Each history pixel takes the sample that falls inside it,
// if one does, as a box filter's new sample, else a little of the samples' bilinear estimate; and what
// it showed before, reprojected through the camera's motion by the depth its light comes from, where
// that depth agrees (else the surface was hidden before: disocclusion), clipped to the statistics of the
// samples around it when anything moved (temporal_neighbourhood.comp). Nothing moving, the history is
// the running mean of its samples, as a still frame's refinement is.
#include "temporal.h"
#include "tone_map.glsl"
layout(local_size_x = TEMPORAL_GROUP_SIZE, local_size_y = TEMPORAL_GROUP_SIZE) in;

layout(std430, binding = TEMPORAL_BINDING_PARAMS) readonly buffer Params { TemporalParams params; };
layout(std430, binding = TEMPORAL_BINDING_SAMPLES) readonly buffer Samples { vec4 samples[]; };
layout(std430, binding = TEMPORAL_BINDING_HISTORY_IN) readonly buffer HistoryIn { vec4 history_in[]; };
layout(std430, binding = TEMPORAL_BINDING_DEPTH_IN) readonly buffer DepthIn { float depth_in[]; };
layout(std430, binding = TEMPORAL_BINDING_HISTORY_OUT) writeonly buffer HistoryOut { vec4 history_out[]; };
layout(std430, binding = TEMPORAL_BINDING_DEPTH_OUT) writeonly buffer DepthOut { float depth_out[]; };
layout(std430, binding = TEMPORAL_BINDING_LDR) writeonly buffer Ldr { uint ldr[]; };
layout(std430, binding = TEMPORAL_BINDING_NEIGHBOURHOOD) readonly buffer Neighbourhood { vec4 neighbourhood[]; };

// The ray through point q (pixels) of a width x height image, as the viewing pass makes it.
vec3 ray_through(TemporalCamera camera, vec2 q, vec2 size) {
    vec2 ndc = vec2((2.0 * q.x / size.x - 1.0) * (size.x / size.y), 1.0 - 2.0 * q.y / size.y) * camera.position.w;
    return normalize(camera.forward.xyz + ndc.x * camera.right.xyz + ndc.y * camera.up.xyz);
}

// Where direction v (from the eye) lands in a width x height image of `camera`, in pixels; false behind it.
bool image_point(TemporalCamera camera, vec3 v, vec2 size, out vec2 q) {
    float z = dot(v, camera.forward.xyz);
    vec2 ndc = vec2(dot(v, camera.right.xyz), dot(v, camera.up.xyz)) / (z * camera.position.w);
    q = vec2((ndc.x / (size.x / size.y) + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
    return z > 1e-6;
}

uint sample_index(ivec2 s) {
    ivec2 size = ivec2(params.sizes.zw);
    s = clamp(s, ivec2(0), size - 1);
    return uint(s.y * size.x + s.x);
}

// Whether a history pixel's inverse depth agrees with the one expected there: a tenth of the depth.
bool same_depth(float expected, float found) {
    return abs(expected - found) <= 0.1 * max(expected, found) + 1e-6;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    uvec2 size = params.sizes.xy;
    if (any(greaterThanEqual(pixel, size))) return;
    uint index = pixel.y * size.x + pixel.x;
    vec2 history_size = vec2(size);
    vec2 sample_size = vec2(params.sizes.zw);
    vec2 jitter = params.jitter.xy;

    // This pixel's centre in the sample frame, and the sample nearest it.
    vec3 d = ray_through(params.now, vec2(pixel) + 0.5, history_size);
    vec2 q;
    image_point(params.now, d, sample_size, q);
    ivec2 nearest = clamp(ivec2(floor(q - jitter)), ivec2(0), ivec2(params.sizes.zw) - 1);
    vec4 sampled = samples[sample_index(nearest)];
    // The nearest sample's offset from this pixel's centre, in history pixels: inside its box, it is this
    // pixel's own (each sample falls in exactly one box).
    vec2 offset = (q - (vec2(nearest) + 0.5 + jitter)) * (history_size.y / sample_size.y);
    bool own = all(greaterThan(offset, vec2(-0.5))) && all(lessThanEqual(offset, vec2(0.5)));
    // The samples' bilinear estimate here, and their neighbourhood's statistics.
    vec2 at = q - jitter - 0.5;
    ivec2 base = ivec2(floor(at));
    vec2 f = at - vec2(base);
    vec3 estimate = vec3(0.0), mean = vec3(0.0), deviation = vec3(0.0);
    for (int k = 0; k < 4; ++k) {
        uint i = sample_index(base + ivec2(k & 1, k >> 1));
        float w = ((k & 1) == 1 ? f.x : 1.0 - f.x) * ((k >> 1) == 1 ? f.y : 1.0 - f.y);
        estimate += w * samples[i].rgb;
        mean += w * neighbourhood[2u * i].rgb;
        deviation += w * neighbourhood[2u * i + 1u].rgb;
    }
    vec3 current = own ? sampled.rgb : estimate;
    float weight = own ? params.blend.x : params.blend.y;
    float inverse_depth = sampled.w;

    // Where this pixel's light was in the history: the point at its depth (or, for the sky, its
    // direction) seen from the camera before.
    vec4 history = vec4(0.0);
    float history_depth = 0.0;
    bool moved = params.blend.w > 0.5;
    bool camera_moved = params.state.y == 1u;
    if (params.state.x == 1u) {
        vec3 point = params.now.position.xyz + d / max(inverse_depth, 1e-30);
        vec3 from_before = inverse_depth > 0.0 ? point - params.before.position.xyz : d;
        float expected = inverse_depth > 0.0 ? 1.0 / length(from_before) : 0.0;
        vec2 before;
        if (image_point(params.before, from_before, history_size, before) && all(greaterThanEqual(before, vec2(0.0))) &&
            all(lessThan(before, history_size))) {
            vec2 at = before - 0.5;
            // A point within a thousandth of a pixel of a pixel centre takes that pixel alone: a still
            // camera keeps its history exact instead of blurring it by rounding.
            bool centred = all(lessThan(abs(at - round(at)), vec2(1e-3)));
            ivec2 base = centred ? ivec2(round(at)) : ivec2(floor(at));
            vec2 f = centred ? vec2(0.0) : at - vec2(base);
            float total = 0.0;
            for (int k = 0; k < 4; ++k) {
                ivec2 t = base + ivec2(k & 1, k >> 1);
                float w = ((k & 1) == 1 ? f.x : 1.0 - f.x) * ((k >> 1) == 1 ? f.y : 1.0 - f.y);
                if (w == 0.0 || any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(size)))) continue;
                uint i = uint(t.y) * size.x + uint(t.x);
                if (camera_moved && !same_depth(expected, depth_in[i])) continue;  // hidden before: disoccluded here
                history += w * history_in[i];
                history_depth += w * depth_in[i];
                total += w;
            }
            if (total > 0.0) {
                history /= total;
                history_depth /= total;
            }
            // Partly disoccluded: the history stands on fewer samples.
            history.w = total > 0.0 ? history.w * total : 0.0;
        }
    }
    if (moved && history.w > 0.0) {
        // The history's colour within what the samples around it say is there now.
        vec3 reach = TEMPORAL_CLIP_DEVIATIONS * deviation;
        history.rgb = clamp(history.rgb, mean - reach, mean + reach);
    }
    float count = min(history.w, params.blend.z);
    vec3 radiance = count > 0.0 ? mix(history.rgb, current, weight / (count + weight)) : current;
    history_out[index] = vec4(radiance, count > 0.0 || weight > 0.0 ? min(count + weight, params.blend.z) : 0.0);
    depth_out[index] = weight > 0.0 || count == 0.0 ? inverse_depth : history_depth;
    ldr[index] = srgb8(radiance, params.jitter.z);
}
