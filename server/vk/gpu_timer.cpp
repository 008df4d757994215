#include "vk/gpu_timer.h"

namespace refract::vk {

GpuTimer::GpuTimer(Context& context, uint32_t max_scopes) : context_(context), max_scopes_(max_scopes) {
    VkQueryPoolCreateInfo info{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    info.queryType = VK_QUERY_TYPE_TIMESTAMP;
    info.queryCount = 2 * max_scopes;
    VkQueryPool pool = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateQueryPool(context.device(), &info, nullptr, &pool));
    pool_ = UniqueQueryPool(context.device(), pool);
    context.set_name(VK_OBJECT_TYPE_QUERY_POOL, pool, "pass timestamps");
}

void GpuTimer::reset(VkCommandBuffer cmd) {
    vkCmdResetQueryPool(cmd, pool_.get(), 0, 2 * max_scopes_);
    names_.clear();
    open_ = false;
}

void GpuTimer::begin(VkCommandBuffer cmd, std::string name) {
    if (open_) throw Error("GpuTimer: scope '" + name + "' begun inside scope '" + names_.back() + "'");
    if (names_.size() >= max_scopes_) throw Error("GpuTimer: more than " + std::to_string(max_scopes_) + " scopes");
    const auto index = static_cast<uint32_t>(2 * names_.size());
    names_.push_back(std::move(name));
    open_ = true;
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, pool_.get(), index);
}

void GpuTimer::end(VkCommandBuffer cmd) {
    if (!open_) throw Error("GpuTimer: end without begin");
    open_ = false;
    const auto index = static_cast<uint32_t>(2 * names_.size() - 1);
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool_.get(), index);
}

std::vector<std::pair<std::string, double>> GpuTimer::read() const {
    std::vector<std::pair<std::string, double>> result;
    if (names_.empty()) return result;
    if (open_) throw Error("GpuTimer: scope '" + names_.back() + "' never ended");
    std::vector<uint64_t> stamps(2 * names_.size());
    REFRACT_VK_CHECK(vkGetQueryPoolResults(context_.device(), pool_.get(), 0,
                                           static_cast<uint32_t>(stamps.size()), stamps.size() * sizeof(uint64_t),
                                           stamps.data(), sizeof(uint64_t),
                                           VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
    const double ns_per_tick = context_.timestamp_period_ns();
    for (size_t i = 0; i < names_.size(); ++i) {
        const uint64_t ticks = stamps[2 * i + 1] >= stamps[2 * i] ? stamps[2 * i + 1] - stamps[2 * i] : 0;
        result.emplace_back(names_[i], static_cast<double>(ticks) * ns_per_tick * 1e-6);
    }
    return result;
}

}  // namespace refract::vk
