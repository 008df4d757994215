// Per-pass GPU milliseconds from timestamp queries: a pass brackets its commands with begin/end, and
// after the submission completes `read` turns the pairs into durations.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "vk/context.h"

namespace refract::vk {

class GpuTimer {
public:
    GpuTimer(Context& context, uint32_t max_scopes = 32);

    // Resets the query pool; call once at the start of each recorded command buffer.
    void reset(VkCommandBuffer cmd);
    void begin(VkCommandBuffer cmd, std::string name);
    void end(VkCommandBuffer cmd);
    // (name, milliseconds) of each scope recorded since reset, in order. Call after the work completed.
    std::vector<std::pair<std::string, double>> read() const;

private:
    Context& context_;
    UniqueQueryPool pool_;
    uint32_t max_scopes_;
    std::vector<std::string> names_;
    bool open_ = false;
};

}  // namespace refract::vk
