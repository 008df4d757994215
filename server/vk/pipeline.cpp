#include "vk/pipeline.h"

#include <string>

namespace refract::vk {

Binding Binding::storage_buffer(uint32_t binding, const Buffer& buffer) {
    return {binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, buffer.get(), VK_NULL_HANDLE};
}
Binding Binding::uniform_buffer(uint32_t binding, const Buffer& buffer) {
    return {binding, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, buffer.get(), VK_NULL_HANDLE};
}
Binding Binding::storage_image(uint32_t binding, const Image3D& image) {
    return {binding, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_NULL_HANDLE, image.view()};
}

ComputePipeline::ComputePipeline(Context& context, std::span<const uint32_t> spirv,
                                 std::span<const BindingLayout> layout, uint32_t push_constant_bytes,
                                 const char* name, std::span<const uint32_t> constants)
    : context_(context),
      spirv_(spirv),
      bindings_(layout.begin(), layout.end()),
      constants_(constants.begin(), constants.end()),
      push_constant_bytes_(push_constant_bytes),
      name_(name) {
    if (push_constant_bytes > context.limits().maxPushConstantsSize)
        throw Error(std::string(name) + ": push constants exceed the device limit");
    if (!context.compiles_on_first_use()) compiled();
}

const ComputePipeline::Compiled& ComputePipeline::compiled() const {
    std::call_once(compiled_->once, [this] { compile(); });
    return *compiled_;
}

void ComputePipeline::compile() const {
    Compiled& into = *compiled_;
    const VkDevice device = context_.device();
    VkShaderModuleCreateInfo module_info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    module_info.codeSize = spirv_.size_bytes();
    module_info.pCode = spirv_.data();
    VkShaderModule module = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateShaderModule(device, &module_info, nullptr, &module));
    into.module = UniqueShaderModule(device, module);
    context_.set_name(VK_OBJECT_TYPE_SHADER_MODULE, module, name_);

    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (const auto& [binding, type] : bindings_)
        bindings.push_back({binding, type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
    VkDescriptorSetLayoutCreateInfo set_info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    set_info.flags = VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR;
    set_info.bindingCount = static_cast<uint32_t>(bindings.size());
    set_info.pBindings = bindings.data();
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateDescriptorSetLayout(device, &set_info, nullptr, &set_layout));
    into.set_layout = UniqueDescriptorSetLayout(device, set_layout);

    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_constant_bytes_};
    VkPipelineLayoutCreateInfo layout_info{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    layout_info.setLayoutCount = 1;
    layout_info.pSetLayouts = &set_layout;
    layout_info.pushConstantRangeCount = push_constant_bytes_ ? 1u : 0u;
    layout_info.pPushConstantRanges = &range;
    VkPipelineLayout pipeline_layout = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreatePipelineLayout(device, &layout_info, nullptr, &pipeline_layout));
    into.layout = UniquePipelineLayout(device, pipeline_layout);

    VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    info.stage.module = module;
    info.stage.pName = "main";
    std::vector<VkSpecializationMapEntry> entries;
    for (uint32_t id = 0; id < constants_.size(); ++id)
        entries.push_back({id, id * static_cast<uint32_t>(sizeof(uint32_t)), sizeof(uint32_t)});
    const VkSpecializationInfo specialization{static_cast<uint32_t>(entries.size()), entries.data(),
                                              constants_.size() * sizeof(uint32_t), constants_.data()};
    if (!constants_.empty()) info.stage.pSpecializationInfo = &specialization;
    info.layout = pipeline_layout;
    VkPipeline pipeline = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline));
    into.pipeline = UniquePipeline(device, pipeline);
    context_.count_compiled_pipeline();
    context_.set_name(VK_OBJECT_TYPE_PIPELINE, pipeline, name_);
}

void ComputePipeline::dispatch(VkCommandBuffer cmd, std::span<const Binding> bindings,
                               const void* push_constants, uint32_t push_bytes, uint32_t groups_x,
                               uint32_t groups_y, uint32_t groups_z) const {
    const auto& limits = context_.limits();
    if (groups_x > limits.maxComputeWorkGroupCount[0] || groups_y > limits.maxComputeWorkGroupCount[1] ||
        groups_z > limits.maxComputeWorkGroupCount[2])
        throw LimitError(std::string(name_) + ": dispatch exceeds the device's workgroup count limit");
    bind(cmd, bindings, push_constants, push_bytes);
    vkCmdDispatch(cmd, groups_x, groups_y, groups_z);
}

void ComputePipeline::dispatch_indirect(VkCommandBuffer cmd, std::span<const Binding> bindings,
                                        const void* push_constants, uint32_t push_bytes, const Buffer& args,
                                        VkDeviceSize offset) const {
    if (offset % 4 != 0 || offset + sizeof(VkDispatchIndirectCommand) > args.size())
        throw Error(std::string(name_) + ": indirect dispatch arguments outside their buffer");
    bind(cmd, bindings, push_constants, push_bytes);
    vkCmdDispatchIndirect(cmd, args.get(), offset);
}

void ComputePipeline::bind(VkCommandBuffer cmd, std::span<const Binding> bindings, const void* push_constants,
                           uint32_t push_bytes) const {
    if (push_bytes != push_constant_bytes_)
        throw Error(std::string(name_) + ": push constants of " + std::to_string(push_bytes) +
                    " bytes, pipeline declares " + std::to_string(push_constant_bytes_));
    std::vector<VkDescriptorBufferInfo> buffer_infos(bindings.size());
    std::vector<VkDescriptorImageInfo> image_infos(bindings.size());
    std::vector<VkWriteDescriptorSet> writes;
    size_t i = 0;
    for (const Binding& b : bindings) {
        VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
        write.dstBinding = b.binding;
        write.descriptorCount = 1;
        write.descriptorType = b.type;
        if (b.type == VK_DESCRIPTOR_TYPE_STORAGE_BUFFER || b.type == VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER) {
            buffer_infos[i] = {b.buffer, 0, VK_WHOLE_SIZE};
            write.pBufferInfo = &buffer_infos[i];
        } else {
            image_infos[i] = {VK_NULL_HANDLE, b.view, VK_IMAGE_LAYOUT_GENERAL};
            write.pImageInfo = &image_infos[i];
        }
        writes.push_back(write);
        ++i;
    }
    const Compiled& made = compiled();
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, made.pipeline.get());
    context_.push_descriptor_set(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, made.layout.get(), 0,
                                 static_cast<uint32_t>(writes.size()), writes.data());
    if (push_bytes)
        vkCmdPushConstants(cmd, made.layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes,
                           push_constants);
}

}  // namespace refract::vk
