// A light-transport pass (photons, resolve, view) compiled once per TransportVariant. The variant is
// given by specialization constants (transport.h), so each pipeline is compiled without the others'
// work: a uniform branch would not do, as lavapipe runs both sides of every branch.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "transport.h"
#include "vk/pipeline.h"
#include "vk/resources.h"

namespace refract::passes {

// Work items (photons, pixels) per part of a dispatch split into parts: the passes whose invocations take
// their work items from a queue in order (take_from_queue) can stop after any part, and a refinement
// step submits between parts, so that waiting work comes before the rest of it (scene::RunOptions).
constexpr uint32_t kWorkPart = 16384;
// Pixels per part of the viewing pass: an eye ray costs about half a photon (the default scene on two
// cores: 1 against 2.2 microseconds), so its parts take about as long as the photons', and a 512 x 512
// frame is 8 submissions, not 16 (each costs a wait for the device).
constexpr uint32_t kViewPart = 2 * kWorkPart;
// Runs between two parts of a split dispatch; it may submit the command buffer and begin another (the
// pass records the next part into recorder.get()). True: the run stops there, and the pass records
// nothing more. Empty: no parts.
using BetweenParts = std::function<bool()>;

// About how long a part of a split dispatch takes at most: what waiting work (a viewer's next edit, a
// newly loaded scene's preview) waits for. Parts of kWorkPart photons take about this long in the default
// scene on two cores; where a work item costs far more (photons that scatter up to 32 times in dense fog:
// 0.75 s a part of kWorkPart), parts shrink to it. Halved from 100 ms (and 2^15 photons): a drag begun
// during refinement waited 62-72 ms for the part in flight (median; at most 151-158), now 44-47 (82-85),
// and a level's refinement took as long as before (docs/perf-log/2026-12-07-first-drag-frames.md).
constexpr double kPartMs = 50.0;

// Sizes the parts of a pass's split dispatches by time, from the rate its parts ran at before (kept by
// the stage that records the pass, for one scene): a part has the items that rate gives kPartMs, in
// multiples of `granule` (a workgroup's items), at most the pass's own largest part. Work items come from
// a queue in order (take_from_queue), so how a dispatch is parted never changes what it computes, only
// when waiting work may come between.
class PartPacer {
public:
    explicit PartPacer(uint32_t granule) : granule_(granule) {}
    // Whether parts are sized by time (true, the default) or are each the largest: the same parts on
    // every run, whatever the machine's load. Returns this pacer.
    PartPacer& paced(bool on) {
        paced_ = on;
        return *this;
    }
    // A dispatch's first part begins to be recorded.
    void begin() { started_ = std::chrono::steady_clock::now(); }
    // The items of the next part: `largest` until a part was timed.
    uint32_t next(uint32_t largest) const;
    // Runs `between` after a part of `items` (it submits that part and waits for it) and takes the part's
    // rate from the time since it began to be recorded. Time `between` spends on other work (another
    // scene's frame) counts too, which only makes the next part smaller. True: the run stops.
    bool between(const BetweenParts& between, uint32_t items);

private:
    uint32_t granule_;
    bool paced_ = true;
    double items_per_ms_ = 0.0;  // of the last part timed; 0 before any
    std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
};

struct TransportVariant {
    uint32_t channels = CHANNELS_RGB;  // how the colour channels travel (TRANSPORT_CONSTANT_CHANNELS)
    bool coverage_fetch = false;       // some coefficient reads the coverage texture (TRANSPORT_CONSTANT_COVERAGE_FETCH)
    bool fresnel = false;              // the object's boundary reflects (TRANSPORT_CONSTANT_FRESNEL)
    bool film = false;                 // ... through a thin film (TRANSPORT_CONSTANT_FILM; with fresnel only)
    bool materials = false;            // several objects, a material each (TRANSPORT_CONSTANT_MATERIALS)
    bool field_atlas = false;          // their field in a field atlas (TRANSPORT_CONSTANT_FIELD_ATLAS; with materials)
    bool medium_field = false;         // volumes add to the medium (TRANSPORT_CONSTANT_MEDIUM_FIELD)
    bool medium_fade = true;           // the medium thins out at the grid's faces (TRANSPORT_CONSTANT_MEDIUM_FADE)
};

// What every transport pass reads first: the frame's parameters, the index field, its coverage, the
// octree's levels and the medium field, at the same bindings in each (TRANSPORT_BINDING_*).
struct TransportInputs {
    const vk::Buffer& params;
    const vk::Image3D& index_field;
    const vk::Image3D& coverage;
    const vk::Buffer& levels;
    const vk::Image3D& medium_extinction;
    const vk::Image3D& medium_scattering;
    const vk::Image3D& medium_emission;
    TransportVariant variant;
};

inline constexpr vk::BindingLayout kTransportInputLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_INDEX_FIELD, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_COVERAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_LEVELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_MEDIUM_EXTINCTION, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_MEDIUM_SCATTERING, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_MEDIUM_EMISSION, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
};
constexpr size_t kTransportInputCount = std::size(kTransportInputLayout);

// A pass's layout: the inputs' bindings, then its own.
template <size_t N>
constexpr std::array<vk::BindingLayout, kTransportInputCount + N> transport_layout(const vk::BindingLayout (&own)[N]) {
    std::array<vk::BindingLayout, kTransportInputCount + N> layout{};
    for (size_t i = 0; i < kTransportInputCount; ++i) layout[i] = kTransportInputLayout[i];
    for (size_t i = 0; i < N; ++i) layout[kTransportInputCount + i] = own[i];
    return layout;
}

// The bindings for transport_layout(own): the inputs', then the pass's own, in the same order.
template <size_t N>
std::array<vk::Binding, kTransportInputCount + N> transport_bindings(const TransportInputs& in, const vk::Binding (&own)[N]) {
    std::array<vk::Binding, kTransportInputCount + N> bindings{
        vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, in.params),
        vk::Binding::storage_image(TRANSPORT_BINDING_INDEX_FIELD, in.index_field),
        vk::Binding::storage_image(TRANSPORT_BINDING_COVERAGE, in.coverage),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_LEVELS, in.levels),
        vk::Binding::storage_image(TRANSPORT_BINDING_MEDIUM_EXTINCTION, in.medium_extinction),
        vk::Binding::storage_image(TRANSPORT_BINDING_MEDIUM_SCATTERING, in.medium_scattering),
        vk::Binding::storage_image(TRANSPORT_BINDING_MEDIUM_EMISSION, in.medium_emission)};
    for (size_t i = 0; i < N; ++i) bindings[kTransportInputCount + i] = own[i];
    return bindings;
}

// Each variant is compiled the first time a frame needs it: most scenes use one or two of the 108, and
// every pipeline created costs a driver compile (LLVM, on lavapipe). Not thread-safe (one thread records).
class TransportPipeline {
public:
    // `spirv` and `name` must outlive the pipeline (the compiled-in shaders and string literals do);
    // `pass_constants`: the pass's own specialization constants, numbered after the transport constants.
    TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                      std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes, const char* name,
                      std::span<const uint32_t> pass_constants = {});
    const vk::ComputePipeline& operator()(TransportVariant variant) const;

private:
    // CHANNELS_* x coverage fetch x (none, Fresnel, film) x (one object, several, several in a field atlas)
    // x medium field x medium fade
    static constexpr size_t kVariants = 3 * 2 * 3 * 3 * 2 * 2;

    vk::Context& context_;
    std::span<const uint32_t> spirv_;
    std::vector<vk::BindingLayout> layout_;
    uint32_t push_constant_bytes_;
    const char* name_;
    std::vector<uint32_t> pass_constants_;
    mutable std::array<std::optional<vk::ComputePipeline>, kVariants> pipelines_;
};

}  // namespace refract::passes
