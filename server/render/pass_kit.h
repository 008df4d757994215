// The compiled pipelines of every pass, created once per Vulkan context and shared by every scene.
#pragma once

#include "passes/direct_light.h"
#include "passes/index_field.h"
#include "passes/octree.h"
#include "passes/photon_trace.h"
#include "passes/radiance_resolve.h"
#include "passes/radiance_spread.h"
#include "passes/temporal_neighbourhood.h"
#include "passes/temporal_reuse.h"
#include "passes/tone_map.h"
#include "passes/view.h"
#include "passes/view_upscale.h"
#include "passes/voxelize.h"
#include "vk/context.h"

namespace refract::scene {

struct PassKit {
    explicit PassKit(vk::Context& context);
    vk::Context& context;
    passes::VoxelizePass voxelize;
    passes::IndexFieldPass index_field;
    passes::OctreePass octree;
    passes::DirectLightPass direct_light;
    passes::PhotonTracePass photon_trace;
    passes::RadianceResolvePass radiance_resolve;
    passes::RadianceSpreadPass radiance_spread;
    passes::ViewPass view;
    passes::ViewUpscalePass view_upscale;
    passes::ToneMapPass tone_map;
    passes::TemporalNeighbourhoodPass temporal_neighbourhood;
    passes::TemporalReusePass temporal_reuse;
};

}  // namespace refract::scene
