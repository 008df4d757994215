// The frame's last stage: eye rays along curved paths through the field, single scattering from the
// radiance grid (the paper's section 4.4), then exposure and tone mapping. It owns the frame's buffers.
#pragma once

#include <cstdint>
#include <vector>

#include "render/frame_inputs.h"
#include "render/frame_recording.h"
#include "render/pass_kit.h"
#include "render/transport_stage.h"
#include "render/volume_stage.h"
#include "vk/commands.h"

namespace refract::scene {

class ViewStage {
public:
    // A still frame's linear image put aside while the scene renders another view, so that its refinement
    // resumes where it stopped when its view comes back (the eye-ray samples of a level are the view's own;
    // the photons they shade from are the scene's).
    struct ParkedFrame {
        uint32_t width = 0, height = 0;
        vk::Buffer hdr;
        int64_t bytes() const { return int64_t{width} * height * int64_t{sizeof(glm::vec4)}; }
    };

    explicit ViewStage(PassKit& kit);

    // The frame's buffers for this size (kept while it stays; a parked image is made anew).
    void allocate(const FrameInputs::View& in);
    // Takes the linear image out; the tone-mapped one stays until the next frame replaces it.
    ParkedFrame park();
    // Puts a parked image back as the frame's, with the other buffers of its size.
    void restore(ParkedFrame parked);
    // Where the viewing pass leaves its eye rays' ends (ViewEnd per pixel): nowhere; for upscale(), an
    // interactive frame traced smaller than its viewer; or apart, a still frame's at the viewer's size,
    // kept for the upscales of the light drags after it (has_still_ends()).
    enum class Ends { none, traced, still };
    // Records the view and tone map when stale; false when the run stopped at a part.
    // `paced`: parts sized by time (RunOptions::paced_parts).
    bool record(FrameRecording& recording, PassSet stale, bool adaptive, Ends ends, bool paced,
                const VolumeStage& volume, const TransportStage& transport);
    // Whether the frame's eye rays' ends are kept: its last view ran with Ends::traced.
    bool has_ends() const { return ends_kept_; }
    // Whether a still frame's ends are kept for a viewer of `width` x `height`: its last view with
    // Ends::still was whole (which view it was, the caller knows).
    bool has_still_ends(uint32_t width, uint32_t height) const {
        return still_ends_kept_ && still_ends_width_ == width && still_ends_height_ == height;
    }
    // The frame brought to a viewer's `width` x `height` (passes::ViewUpscalePass; has_ends()), in a
    // submission of its own; with `still_ends` (has_still_ends()), each viewer pixel's eye ray is the
    // still frame's.
    void upscale(uint32_t width, uint32_t height, bool still_ends, const VolumeStage& volume,
                 const TransportStage& transport);

    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }
    // The frame's linear radiance (vec4 per pixel; w the inverse depth its light comes from).
    const vk::Buffer& hdr() const { return hdr_; }
    std::vector<glm::vec4> read_hdr() const;
    std::vector<uint32_t> read_ldr() const;
    // The last upscale()'s frame: its size, linear radiance and sRGB pixels.
    uint32_t viewer_width() const { return viewer_width_; }
    uint32_t viewer_height() const { return viewer_height_; }
    std::vector<glm::vec4> read_viewer_hdr() const;
    std::vector<uint32_t> read_viewer_ldr() const;
    // Device memory of the ends and the upscaled frame, beside the frame's own.
    int64_t upscale_bytes() const;

private:
    PassKit& kit_;
    uint32_t width_ = 0, height_ = 0;
    vk::Buffer hdr_, ldr_, refine_;
    vk::Buffer ends_;     // made with the first frame that keeps its ends
    vk::Buffer no_ends_;  // bound in their place otherwise (nothing writes it)
    bool ends_kept_ = false;
    vk::Buffer still_ends_;  // Ends::still, whatever size the frame has since
    uint32_t still_ends_width_ = 0, still_ends_height_ = 0;
    bool still_ends_kept_ = false;
    uint32_t viewer_width_ = 0, viewer_height_ = 0;
    vk::Buffer viewer_hdr_, viewer_ldr_;
    vk::CommandRecorder upscale_recorder_;
    passes::PartPacer parts_{1};  // the viewing pass's parts, in rows of tiles, sized by its last rate
};

}  // namespace refract::scene
