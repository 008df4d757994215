#include "passes/radiance_resolve.h"

#include "radiance_resolve_spv.h"
#include "transport.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER},
    {TRANSPORT_BINDING_ACCUM_RG, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_BX, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_YZ, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_FLOOR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_RADIANCE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
};
}  // namespace

RadianceResolvePass::RadianceResolvePass(vk::Context& context)
    : pipeline_(context, radiance_resolve_spv, kLayout, "radiance resolve") {}

void RadianceResolvePass::record(vk::CommandRecorder& recorder, const vk::Buffer& params,
                                 const PhotonAccumulators& accum, bool grey, const vk::Image3D& radiance,
                                 const vk::Image3D& flux, const vk::Image3D& floor_map) const {
    const uint64_t items = flux.extent().count() + uint64_t{floor_map.extent().x} * floor_map.extent().y;
    const auto groups = vk::linear_groups(items, TRANSPORT_GROUP_SIZE);
    pipeline_({grey, false}).dispatch(recorder.get(),
                             {vk::Binding::uniform_buffer(TRANSPORT_BINDING_PARAMS, params),
                              vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_RG, accum.voxel[0]),
                              vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_BX, accum.voxel[1]),
                              vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_YZ, accum.voxel[2]),
                              vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_FLOOR, accum.floor),
                              vk::Binding::storage_image(TRANSPORT_BINDING_RADIANCE, radiance),
                              vk::Binding::storage_image(TRANSPORT_BINDING_FLUX, flux),
                              vk::Binding::storage_image(TRANSPORT_BINDING_FLOOR_MAP, floor_map)},
                             nullptr, 0, groups.x, groups.y);
}

}  // namespace refract::passes
