#include "render/scene_gpu.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string_view>

#include "render/renderer.h"

namespace refract::scene {

PassKit::PassKit(vk::Context& ctx)
    : context(ctx),
      voxelize(ctx),
      index_field(ctx),
      octree(ctx),
      direct_light(ctx),
      photon_trace(ctx),
      radiance_resolve(ctx),
      lit_pyramid(ctx),
      view(ctx),
      tone_map(ctx),
      linear_sampler(vk::make_linear_sampler(ctx)) {}

int64_t estimate_scene_bytes(const passes::GridGeometry& grid, uint64_t field_voxels, uint64_t object_voxels,
                             uint64_t radiance_voxels, uint32_t width, uint32_t height) {
    // Per field voxel: index field (16), coverage image (8), pyramid (8 x 1/7: levels 1 and up), levels
    // (4 / 8). Per radiance voxel: packed accumulators (RADIANCE_FLUX_WORDS x 8, and 8 for red and green
    // in colour), net flux (16), coloured radiance (16); the direct light's edge list (4) and reach bits
    // (1/8 + rows). Per voxel of the objects' boxes: coverage and the voxelize pass's scratch (4 + 4), and
    // its per-axis scratch (12) while it runs. Over the lattice: the lit pyramid and a field atlas's map.
    const int64_t per_field_voxel = 16 + 8 + 2 + 1;
    const int64_t per_radiance_voxel = (RADIANCE_FLUX_WORDS + 1) * 8 + 16 + 16 + 4 + 1;
    const int64_t per_object_voxel = 4 + 4 + 12;
    const int64_t lattice = int64_t{passes::lit_pyramid_offsets(grid.coarsened(grid.light_factor))[LIT_LEVELS]} * 4 +
                            static_cast<int64_t>(grid.dims.count() / (FIELD_CELL * FIELD_CELL * FIELD_CELL)) * 4;
    const int64_t floor = int64_t{passes::floor_map_texels(grid)} * passes::floor_map_texels(grid) * (12 + 8);
    const int64_t light_map = int64_t{passes::light_map_capacity(grid)} * passes::light_map_capacity(grid) * 2 * 4;
    // Per pixel: HDR (16), sRGB (4), a slot in the refinement list (4).
    return static_cast<int64_t>(field_voxels) * per_field_voxel + static_cast<int64_t>(object_voxels) * per_object_voxel +
           static_cast<int64_t>(radiance_voxels) * per_radiance_voxel + lattice + floor + light_map +
           int64_t{width} * height * 24;
}

int64_t estimate_environment_bytes(const image::EnvironmentMap* image) {
    const int64_t texels = image ? int64_t{image->width} * image->height + image->height : 2;
    return texels * static_cast<int64_t>(sizeof(glm::vec4));
}

FieldAtlas field_atlas_for(const passes::GridGeometry& lattice, const std::map<std::string, passes::ObjectBox>& boxes, bool dense,
                           uint32_t max_side) {
    if (dense) return dense_field_atlas(lattice);
    std::vector<std::pair<glm::uvec3, glm::uvec3>> ranges;
    for (const auto& [name, b] : boxes) ranges.push_back({b.offset, b.offset + glm::uvec3(b.box.dims.x, b.box.dims.y, b.box.dims.z)});
    FieldAtlas sparse;
    try {
        sparse = sparse_field_atlas(lattice, ranges, passes::octree_layout(lattice.dims).max_level, max_side);
    } catch (const std::length_error& e) {
        throw RenderError(e.what());
    }
    // A step through the atlas's map costs a quarter more (transport.h): worth it where the atlas holds
    // under half the lattice's voxels.
    if (2 * sparse.dims.count() >= lattice.dims.count()) return dense_field_atlas(lattice);
    return sparse;
}

uint32_t object_apron(double sigma) {
    // The B-spline reaches 1.5 voxels past the surface, the lattice Gaussian ceil(3 sigma) taps more.
    return static_cast<uint32_t>(std::ceil(3.0 * std::max(sigma, 0.0))) + 4u;
}

std::map<std::string, passes::ObjectBox> object_boxes(const passes::GridGeometry& lattice, const WorldMeshes& worlds,
                                              double sigma) {
    std::map<std::string, passes::ObjectBox> boxes;
    for (const auto& [name, world] : worlds)
        boxes.emplace(name, worlds.size() == 1 ? passes::ObjectBox{lattice, glm::uvec3(0u)}
                                               : passes::object_box(lattice, world, object_apron(sigma)));
    return boxes;
}

namespace {
passes::VoxelRange range_of(const passes::ObjectBox& b) {
    return {b.offset, b.offset + glm::uvec3(b.box.dims.x, b.box.dims.y, b.box.dims.z)};
}

// The smallest range holding both.
passes::VoxelRange joined(const passes::VoxelRange& a, const passes::VoxelRange& b) {
    if (a.empty()) return b;
    if (b.empty()) return a;
    return {glm::min(a.first, b.first), glm::max(a.end, b.end)};
}

// Identifies a world mesh's content: an object whose mesh hashes the same keeps its coverage.
size_t mesh_hash(const mesh::Mesh& mesh) {
    const std::hash<std::string_view> hash;
    const size_t positions = hash({reinterpret_cast<const char*>(mesh.positions.data()), mesh.positions.size() * sizeof(glm::vec3)});
    const size_t triangles = hash({reinterpret_cast<const char*>(mesh.triangles.data()), mesh.triangles.size() * sizeof(glm::uvec3)});
    return positions ^ (triangles + 0x9e3779b97f4a7c15ull + (positions << 6) + (positions >> 2));
}
}  // namespace

SceneGpu::SceneGpu(PassKit& kit) : kit_(kit), recorder_(kit.context, "scene passes"), timer_(kit.context) {}

void SceneGpu::allocate_volume(const passes::GridGeometry& grid) {
    // Drop the old volume first so peak memory is one volume, not two.
    objects_.clear();
    pyramid_ = {};
    levels_ = {};
    index_field_ = {};
    coverage_image_ = {};
    atlas_ = {};
    accum_.reset();
    radiance_ = {};
    flux_ = {};
    floor_map_ = {};
    grid_ = grid;
    built_ = 0;
}

void SceneGpu::allocate_field(FieldAtlas atlas) {
    vk::Context& ctx = kit_.context;
    const auto storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                         VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
    pyramid_ = {};
    levels_ = {};
    index_field_ = {};
    coverage_image_ = {};
    index_field_ = vk::Image3D(ctx, atlas.dims, VK_FORMAT_R32G32B32A32_SFLOAT, "index field");
    coverage_image_ = vk::Image3D(ctx, atlas.dims, VK_FORMAT_R32G32_SFLOAT, "coverage and object image");
    const passes::OctreeLayout octree = passes::octree_layout(atlas.dims);
    pyramid_ = vk::Buffer(ctx, std::max<uint64_t>(octree.node_count, 1) * 2 * sizeof(float), storage,
                          vk::MemoryUse::device, "octree pyramid");
    levels_ = vk::Buffer(ctx, octree.cell_count * sizeof(uint32_t), storage, vk::MemoryUse::device, "octree levels");
    atlas_map_ = {};
    if (!atlas.dense) {
        atlas_map_ = vk::Buffer(ctx, std::max<size_t>(atlas.map.size(), 1) * sizeof(uint32_t),
                                VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, vk::MemoryUse::upload, "field atlas map");
        atlas_map_.write(atlas.map.data(), atlas.map.size() * sizeof(uint32_t));
    }
    atlas_ = std::move(atlas);
    built_ &= ~(kIndexField | kOctree);
}

void SceneGpu::allocate_transport(uint32_t photon_exit_count, bool record_exits, uint32_t radiance_factor,
                                  uint32_t channels) {
    vk::Context& ctx = kit_.context;
    const bool to_grey = channels == CHANNELS_GREY;
    const uint32_t floor_texels = passes::floor_map_texels(grid_);
    const uint32_t exits = record_exits ? photon_exit_count : 1u;
    const uint32_t f = radiance_factor;
    const vk::Extent3 radiance_dims = grid_.coarsened(f * grid_.light_factor);
    if (!accum_ || floor_texels != floor_texels_ || exits != exit_capacity_ || f != radiance_factor_ ||
        to_grey != grey()) {
        accum_.reset();
        accum_.emplace(passes::make_photon_accumulators(ctx, grid_.coarsened(grid_.light_factor), radiance_dims, floor_texels,
                                                        passes::light_map_capacity(grid_), exits, to_grey));
        exit_capacity_ = exits;
    }
    if (!flux_.get() || f != radiance_factor_) {
        flux_ = {};
        flux_ = vk::Image3D(ctx, radiance_dims, VK_FORMAT_R32G32B32A32_SFLOAT, "net flux and fluence grid");
        radiance_factor_ = f;
    }
    // Per-channel fluence only for coloured transport; grey transport binds a single texel it never reads.
    const vk::Extent3 colour_dims = to_grey ? vk::Extent3{1, 1, 1} : radiance_dims;
    if (!radiance_.get() || !(radiance_.extent() == colour_dims)) {
        radiance_ = {};
        radiance_ = vk::Image3D(ctx, colour_dims, VK_FORMAT_R32G32B32A32_SFLOAT, "radiance grid (per channel)");
    }
    channels_ = channels;
    if (floor_texels != floor_texels_ || !floor_map_.get()) {
        floor_map_ = vk::Image3D(ctx, {floor_texels, floor_texels, 1}, VK_FORMAT_R16G16B16A16_SFLOAT,
                                 "floor caustic map");
        floor_texels_ = floor_texels;
    }
}

void SceneGpu::allocate_frame(uint32_t width, uint32_t height) {
    if (width == width_ && height == height_ && hdr_.get()) return;
    vk::Context& ctx = kit_.context;
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    hdr_ = {};
    ldr_ = {};
    refine_ = {};
    hdr_ = vk::Buffer(ctx, uint64_t{width} * height * sizeof(glm::vec4), usage, vk::MemoryUse::readback, "hdr frame");
    ldr_ = vk::Buffer(ctx, uint64_t{width} * height * sizeof(uint32_t), usage, vk::MemoryUse::readback, "ldr frame");
    refine_ = vk::Buffer(ctx, sizeof(shaders::WorkListHeader) + uint64_t{width} * height * sizeof(uint32_t),
                         usage | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                         vk::MemoryUse::device, "view refinement list");
    width_ = width;
    height_ = height;
}

RunStats SceneGpu::run(PassSet stale, const protocol::SceneDocument& document, const WorldMeshes& worlds,
                       const IndexGrid* grid_asset, const RunOptions& options,
                       const image::EnvironmentMap* environment) {
    using protocol::IndexFieldKind;
    const bool imported = document.object().index_field == IndexFieldKind::grid;  // then the only object
    // Only a rebuilt volume can move the grid: otherwise keep the resident one.
    const bool rebuild = (stale & kVoxelize) || !(built_ & kVoxelize);
    passes::GridGeometry grid = grid_;
    if (rebuild && imported) {
        if (!grid_asset) throw RenderError("the scene's index field grid is not loaded");
        const auto& b = grid_asset->bounds;
        grid.origin = glm::vec3(static_cast<float>(b.min[0]), static_cast<float>(b.min[1]), static_cast<float>(b.min[2]));
        grid.voxel_size = static_cast<float>((b.max[0] - b.min[0]) / grid_asset->nx);
        grid.dims = {grid_asset->nx, grid_asset->ny, grid_asset->nz};
    } else if (rebuild) {
        grid = passes::grid_for(document, worlds);
    }
    // Anything never built, or built for another grid, runs whatever it needs.
    if (!(grid == grid_) || !index_field_.get()) {
        allocate_volume(grid);
        stale = kAllPasses;
    }
    // Another radiance-grid resolution, deposit estimator or bounce cap (interactive <-> still) or kind of
    // transport means new photons into a new grid.
    const uint32_t channels = passes::transport_channels(document);
    const uint32_t bounces = passes::photon_bounces(document, options.bounce_cap);
    if (!grid_made_for(document, options)) built_ &= ~(kPhotons | kView | kToneMap);
    sampled_deposits_ = options.sampled_deposits;
    bounces_ = bounces;
    const PassSet asked = stale;
    // A refinement step adds a batch to the running mean of those before it. Given way before its first
    // resolve, it leaves that mean in the images, and the frame made from it, as they were (each photon
    // run clears the sums it adds to first): a drag that interrupts it shades from those batches.
    bool mean_untouched = options.photon_batch > 0 && (built_ & kPhotons) && photon_batches_ == options.photon_batch;
    stale = passes_for(stale) & options.limit;
    allocate_frame(document.image.width, document.image.height);
    const bool several = document.objects.size() > 1;
    // The objects' boxes (when the voxelize pass runs, which reads `worlds`), and where their field is
    // stored: a new layout means new field images.
    const double sigma = document.volume.smoothing;
    std::map<std::string, passes::ObjectBox> boxes;
    if ((stale & kVoxelize) && !imported) boxes = object_boxes(grid_, worlds, sigma);
    // A new layout of an atlas built before carries the clusters that stay over from the old images
    // (held until the submission completes), so that an edit of one object composes that one's cluster.
    bool field_fresh = false;
    struct {
        vk::Image3D index_field, coverage;
        FieldAtlas atlas;
    } carried;
    if (stale & kVoxelize) {
        FieldAtlas layout = field_atlas_for(grid_, boxes, imported || !several, kit_.context.limits().maxImageDimension3D);
        if (!(layout == atlas_) || !index_field_.get()) {
            if ((built_ & kIndexField) && !atlas_.dense && !layout.dense) {
                carried.index_field = std::move(index_field_);
                carried.coverage = std::move(coverage_image_);
                carried.atlas = atlas_;
            }
            allocate_field(std::move(layout));
            field_fresh = true;
        }
    }

    passes::TransportOptions transport_options;
    transport_options.fixed_step = options.fixed_step;
    transport_options.view_step = options.view_step;
    transport_options.max_level = passes::octree_layout(grid_.dims).max_level;
    transport_options.radiance_factor = options.radiance_factor * grid_.light_factor;
    transport_options.direct_light = options.direct_light;
    transport_options.photon_batch = options.photon_batch;
    transport_options.view_sample = options.view_sample;
    transport_options.bounce_cap = options.bounce_cap;
    // The environment's map, made again when the environment, its image or the floor (which hides what
    // lies below the horizon from photons) changed; a placeholder texel when it lights nothing, so the
    // passes always address a buffer.
    if (!environment_map_.get() || environment != environment_image_ || !(document.environment == environment_document_) ||
        document.floor.enabled != environment_floor_) {
        const image::EnvironmentMap* image = document.environment.type == protocol::EnvironmentKind::image ? environment : nullptr;
        if (document.environment.type == protocol::EnvironmentKind::image && image == nullptr)
            throw RenderError("environment image '" + document.environment.image + "' is not loaded");
        environment_light_ = passes::make_environment_light(document, image);
        const uint64_t bytes = environment_light_.texels.size() * sizeof(glm::vec4);
        environment_map_ = {};
        environment_map_ = vk::Buffer(kit_.context, bytes, VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
                                      vk::MemoryUse::upload, "environment map");
        environment_map_.write(environment_light_.texels.data(), bytes);
        environment_light_.texels = {};  // the device holds the map; a large one is not kept twice
        environment_image_ = environment;
        environment_document_ = document.environment;
        environment_floor_ = document.floor.enabled;
    }
    transport_options.environment = &environment_light_;
    light_params_ = passes::make_transport_params(document, grid_, transport_options);
    // Several objects: their materials, by the object numbers the index field holds per voxel.
    if (several) {
        std::vector<shaders::Material> table;
        for (const auto& [name, object] : document.objects) table.push_back(passes::material_for(object, document.medium, grid_));
        if (!materials_.get())  // room for the most objects a scene may hold
            materials_ = vk::Buffer(kit_.context, sizeof(shaders::Material) * protocol::kMaxObjects,
                                    VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, vk::MemoryUse::upload, "object materials");
        materials_.write(table.data(), table.size() * sizeof(shaders::Material));
    }
    uint32_t most_photons = 0;  // of one light's dispatch (with the environment's, for the first)
    for (const auto& light : light_params_) most_photons = std::max(most_photons, light.photon_info.x);
    if (stale & kPhotons)
        allocate_transport(passes::photon_exit_count(most_photons, channels), options.record_photon_exits,
                           options.radiance_factor, channels);
    while (params_buffers_.size() < light_params_.size())
        params_buffers_.emplace_back(kit_.context, sizeof(shaders::TransportParams), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                     vk::MemoryUse::upload, "transport params");
    auto halves = [](VkDeviceAddress a) { return glm::uvec2(static_cast<uint32_t>(a), static_cast<uint32_t>(a >> 32)); };
    for (size_t i = 0; i < light_params_.size(); ++i) {
        shaders::TransportParams& params = light_params_[i];
        params.flags.x = options.record_photon_exits ? 1u : 0u;
        if (accum_) params.radiance_sums = glm::uvec4(halves(accum_->red_green.address()), halves(accum_->flux.address()));
        params.environment_map = glm::uvec4(halves(environment_map_.address()), 0u, 0u);
        if (several) params.materials = glm::uvec4(halves(materials_.address()), params.materials.z, 0u);
        if (!atlas_.dense)
            params.field_atlas = glm::uvec4(halves(atlas_map_.address()), 0u, 0u);
        params.atlas_dims = glm::uvec4(atlas_.dims.x, atlas_.dims.y, atlas_.dims.z, 0u);
        params_buffers_[i].write(&params, sizeof(params));
    }
    const shaders::TransportParams& params = light_params_.front();
    const vk::Buffer& params_buffer = params_buffers_.front();  // the first light's, and every pass's but photons'

    // Grid values for the index-field pass: the imported field, or a placeholder it never reads.
    if (stale & kIndexField) {
        const uint64_t count = imported ? grid_.dims.count() : 1;
        grid_values_ = vk::Buffer(kit_.context, count * sizeof(float), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                  vk::MemoryUse::upload, "imported index grid");
        if (imported) grid_values_.write(grid_asset->n.data(), count * sizeof(float));
    }

    // One submission for every stale pass (with give_way: one per volume pass and per part of the photons
    // and view, so that the run can stop after any); each pass is bracketed by timestamps.
    VkCommandBuffer cmd = recorder_.begin();
    timer_.reset(cmd);
    std::vector<std::pair<std::string, double>> earlier_ms;  // pass times of this run's earlier submissions
    // Submits the parts recorded so far, `pass` unfinished (begun or next). Giving way leaves the passes
    // before it built, and it and the passes asked for after it not (a photon pass stopped halfway holds
    // part of a batch).
    auto submit_part = [&](Pass pass) {
        recorder_.submit_and_wait();
        for (auto& timing : timer_.read()) earlier_ms.push_back(std::move(timing));
        if (options.give_way()) {
            // A pass after `pass` that runs only because an earlier one does keeps its output, made before.
            if (!(pass == kPhotons && mean_untouched))
                built_ = (built_ | (stale & (pass - 1))) & ~((asked | pass) & ~(pass - 1));
            throw Superseded();
        }
        cmd = recorder_.begin();
        timer_.reset(cmd);
        recorder_.compute_barrier();  // the parts before wrote what the next reads and adds to
    };
    // Between two parts of `pass`, timed under its name.
    auto between_parts = [&](Pass pass) -> passes::BetweenParts {
        if (!options.give_way) return {};
        return [&, pass] {
            timer_.end(cmd);
            submit_part(pass);
            timer_.begin(cmd, pass_names(pass));
        };
    };
    // Uploads and scratch the recorded commands use; they live until the submission completes.
    std::vector<passes::VoxelizeUploads> uploads;
    std::vector<vk::Buffer> scratch;
    vk::Buffer coverage_upload;
    std::vector<std::string> voxelized;
    passes::VoxelRange moved;  // where the objects voxelized now lay before and lie now
    vk::Buffer zeros;          // the medium's coverage over the region the index field is remade over
    const passes::VoxelRange whole_lattice{glm::uvec3(0u), glm::uvec3(grid_.dims.x, grid_.dims.y, grid_.dims.z)};
    const passes::VoxelRange whole_field{glm::uvec3(0u), glm::uvec3(atlas_.dims.x, atlas_.dims.y, atlas_.dims.z)};
    passes::VoxelRange field_changed = whole_field;  // where the field images changed since the octree was made
    if (field_fresh) {
        for (const vk::Image3D* image : {&index_field_, &coverage_image_}) recorder_.init_image(*image);
    }
    if (stale & kPhotons && !(built_ & kPhotons)) {
        for (const vk::Image3D* image : {&radiance_, &flux_, &floor_map_}) recorder_.init_image(*image);
    }
    if (stale & kVoxelize) {
        timer_.begin(cmd, "voxelize");
        const auto storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                             VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
        std::erase_if(objects_, [&](const auto& held) { return !document.objects.contains(held.first); });
        if (imported) {
            ObjectVolume& volume = objects_[document.objects.begin()->first];
            volume.box = {grid_, glm::uvec3(0u)};
            volume.coverage = vk::Buffer(kit_.context, grid_.dims.count() * sizeof(float), storage,
                                         vk::MemoryUse::device, "coverage");
            // An imported field has no mesh: coverage is where n departs from the medium.
            std::vector<float> coverage(grid_.dims.count());
            float n_max = static_cast<float>(document.medium.ior);
            for (float n : grid_asset->n) n_max = std::max(n_max, n);
            const float span = std::max(n_max - static_cast<float>(document.medium.ior), 1e-6f);
            for (size_t i = 0; i < coverage.size(); ++i)
                coverage[i] = std::clamp((grid_asset->n[i] - static_cast<float>(document.medium.ior)) / span, 0.0f, 1.0f);
            coverage_upload = vk::Buffer(kit_.context, coverage.size() * sizeof(float), VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                         vk::MemoryUse::upload, "coverage upload");
            coverage_upload.write(coverage.data(), coverage.size() * sizeof(float));
            recorder_.copy(coverage_upload, volume.coverage, coverage.size() * sizeof(float));
            voxelized.push_back(document.objects.begin()->first);
        } else {
            // Only the objects whose coverage no longer fits their world mesh, box or smoothing.
            for (const auto& [name, box] : boxes) {
                const mesh::Mesh& world = worlds.at(name);
                const size_t hash = mesh_hash(world);
                auto held = objects_.find(name);
                if (!options.revoxelize && held != objects_.end() && held->second.mesh_hash == hash &&
                    held->second.smoothing == sigma && held->second.box.box == box.box)
                    continue;
                if (held != objects_.end()) moved = joined(moved, range_of(held->second.box));
                moved = joined(moved, range_of(box));
                ObjectVolume& volume = objects_[name];
                volume.box = box;
                volume.mesh_hash = hash;
                volume.smoothing = sigma;
                voxelized.push_back(name);
                if (box.empty()) continue;  // outside the lattice: nothing to voxelize
                const VkDeviceSize bytes = box.box.dims.count() * sizeof(float);
                if (!volume.coverage.get() || volume.coverage.size() != bytes)
                    volume.coverage = vk::Buffer(kit_.context, bytes, storage, vk::MemoryUse::device, "coverage");
                scratch.emplace_back(kit_.context, bytes, storage, vk::MemoryUse::device, "coverage scratch");
                uploads.push_back(kit_.voxelize.record(recorder_, world, box.box, static_cast<float>(sigma),
                                                       scratch.back(), volume.coverage));
            }
        }
        recorder_.compute_barrier();
        timer_.end(cmd);
        if (options.give_way && (stale & kIndexField)) submit_part(kIndexField);
    }
    if (stale & kIndexField) {
        timer_.begin(cmd, "index_field");
        std::vector<passes::ObjectField> fields;
        uint32_t number = 0;
        for (const auto& [name, object] : document.objects) {
            const ObjectVolume& volume = objects_.at(name);
            ++number;
            if (!volume.box.empty())
                fields.push_back({object, volume.box.box, volume.box.offset, volume.coverage, several ? number : 0u});
        }
        // The whole lattice, unless the field of these very objects (by name, so by number) over this
        // medium is resident and only some objects moved or changed their index: then their boxes.
        passes::VoxelRange region{glm::uvec3(0u), glm::uvec3(grid_.dims.x, grid_.dims.y, grid_.dims.z)};
        const bool same_objects = std::equal(composed_objects_.begin(), composed_objects_.end(), document.objects.begin(),
                                             document.objects.end(), [](const auto& a, const auto& b) { return a.first == b.first; });
        const bool resident = (built_ & kIndexField) || carried.index_field.get();
        if (several && resident && same_objects && composed_medium_ior_ == document.medium.ior) {
            region = moved;
            for (const auto& [name, object] : document.objects) {
                const protocol::Object& was = composed_objects_.at(name);
                if (was.index_field != object.index_field || was.ior != object.ior || was.maxwell_n0 != object.maxwell_n0)
                    region = joined(region, range_of(objects_.at(name).box));
            }
        }
        // New atlas images, or a field composed whole, start as the medium everywhere, the room between
        // the clusters too (the octree's ranges read a voxel past a cluster's edge, as in the lattice).
        const bool whole = region.first == whole_lattice.first && region.end == whole_lattice.end;
        const bool cleared = !atlas_.dense && (field_fresh || whole);
        if (cleared) {
            const float n_medium = static_cast<float>(document.medium.ior);
            recorder_.clear(index_field_, {n_medium, 0.0f, 0.0f, 0.0f});
            recorder_.clear(coverage_image_, {0.0f, 0.0f, 0.0f, 0.0f});
            recorder_.compute_barrier();
        }
        // The clusters that stay are copied across; the others are composed anew, whole.
        if (carried.index_field.get() && !whole) {
            for (const FieldAtlas::Cluster& c : atlas_.clusters) {
                const auto was = std::find_if(carried.atlas.clusters.begin(), carried.atlas.clusters.end(),
                                              [&](const FieldAtlas::Cluster& o) { return o.first == c.first && o.end == c.end; });
                if (was == carried.atlas.clusters.end()) {
                    region = joined(region, {c.first, c.end});
                    continue;
                }
                const glm::uvec3 e = c.extent();
                for (const auto& [from, to] : {std::pair{&carried.index_field, &index_field_}, std::pair{&carried.coverage, &coverage_image_}})
                    recorder_.copy(*from, {was->atlas_first.x, was->atlas_first.y, was->atlas_first.z}, *to,
                                   {c.atlas_first.x, c.atlas_first.y, c.atlas_first.z}, {e.x, e.y, e.z});
            }
            recorder_.compute_barrier();
        }
        std::vector<passes::FieldBlock> blocks;
        for (const FieldAtlas::Cluster& c : atlas_.clusters) blocks.push_back({{c.first, c.end}, c.atlas_first});
        if (several && !region.empty() && !cleared) {
            zeros = vk::Buffer(kit_.context, std::max<uint64_t>(passes::largest_part(blocks, region), 1) * sizeof(float),
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                               vk::MemoryUse::device, "medium coverage");
            recorder_.fill(zeros, 0u);
            recorder_.transfer_to_compute_barrier();
        }
        field_changed = {};
        if (!region.empty())
            field_changed = kit_.index_field.record(recorder_, document.medium, grid_, fields, blocks, region,
                                                    cleared ? nullptr : (several ? &zeros : &grid_values_), grid_values_,
                                                    index_field_, coverage_image_);
        composed_objects_ = document.objects;
        composed_medium_ior_ = document.medium.ior;
        recorder_.compute_barrier();
        timer_.end(cmd);
        if (options.give_way && (stale & kOctree)) submit_part(kOctree);
    }
    if (stale & kOctree) {
        timer_.begin(cmd, "octree");
        // Over what the changed voxels reach, when the resident octree is the old field's at this epsilon.
        const float epsilon = passes::octree_epsilon(document);
        const bool resident = (built_ & kOctree) && epsilon == octree_epsilon_;
        kit_.octree.record(recorder_, index_field_, epsilon, resident ? field_changed : whole_field, pyramid_, levels_);
        octree_epsilon_ = epsilon;
        recorder_.compute_barrier();
        timer_.end(cmd);
        if (options.give_way && (stale & kPhotons)) submit_part(kPhotons);
    }
    const passes::TransportVariant variant{channels_, params.flags.y == COVERAGE_FETCH || params.flags.z == COVERAGE_FETCH,
                                           passes::fresnel_reflects(document), passes::film_reflects(document), several,
                                           !atlas_.dense};
    auto inputs_for = [&](const vk::Buffer& light_params) {
        return passes::TransportInputs{light_params, index_field_, coverage_image_, levels_, kit_.linear_sampler.get(), variant};
    };
    const passes::TransportInputs inputs = inputs_for(params_buffer);
    if (stale & kPhotons) {
        timer_.begin(cmd, "photons");
        passes::clear_photon_accumulators(recorder_, *accum_, grey());
        // Light by light: each one's sums hold its own unbent light (transport.h), so each is resolved into
        // the radiance grid and floor map, the first replacing this batch's share and the rest adding theirs.
        // A refinement step gives way after the direct light and after each resolve too (each a tenth of
        // a second or more on two cores), not only between parts of the photons.
        const passes::BetweenParts gap = between_parts(kPhotons);
        for (size_t i = 0; i < light_params_.size(); ++i) {
            const shaders::TransportParams& light = light_params_[i];
            const passes::TransportInputs light_inputs = inputs_for(params_buffers_[i]);
            if (i > 0) passes::clear_for_next_light(recorder_, *accum_, grey());
            if (light.direct_light.w > 0.5f) {
                kit_.direct_light.record(recorder_, light_inputs, *accum_, static_cast<uint32_t>(light.direct_light.x),
                                         grid_.coarsened(transport_options.radiance_factor));
                recorder_.compute_barrier();
                if (gap) gap();
            }
            kit_.photon_trace.record(recorder_, light_inputs, *accum_, light.photon_info.x, options.sampled_deposits,
                                     bounces > 0, between_parts(kPhotons));
            recorder_.compute_barrier();
            kit_.radiance_resolve.record(recorder_, params_buffers_[i], *accum_, grey(), radiance_, flux_, floor_map_);
            mean_untouched = false;
            recorder_.compute_barrier();
            if (gap) gap();
        }
        kit_.lit_pyramid.record(recorder_, params_buffer, flux_, accum_->lit_blocks, grid_.coarsened(grid_.light_factor));
        recorder_.compute_barrier();
        timer_.end(cmd);
        photon_batches_ = options.photon_batch + 1;
        if (options.give_way && (stale & kView)) submit_part(kView);
    }
    if (stale & kView) {
        timer_.begin(cmd, "view");
        kit_.view.record(recorder_, inputs, radiance_, flux_, floor_map_,
                         {hdr_, accum_->stats, accum_->lit_blocks, refine_}, width_, height_, options.adaptive_view,
                         between_parts(kView));
        recorder_.compute_barrier();
        timer_.end(cmd);
    }
    if (stale & kToneMap) {
        timer_.begin(cmd, "tone_map");
        kit_.tone_map.record(recorder_, params_buffer, hdr_, ldr_, width_, height_);
        timer_.end(cmd);
    }
    recorder_.to_host_barrier();
    // A failure here leaves built_ as it was: the caller drops this scene's state and rebuilds.
    recorder_.submit_and_wait();
    built_ |= stale;

    RunStats stats;
    stats.ran = stale;
    stats.voxelized = std::move(voxelized);
    // One entry per pass: the parts of a pass split over submissions summed.
    for (auto& timing : timer_.read()) earlier_ms.push_back(std::move(timing));
    for (const auto& [name, ms] : earlier_ms) {
        auto same = std::find_if(stats.gpu_ms.begin(), stats.gpu_ms.end(), [&](const auto& t) { return t.first == name; });
        if (same == stats.gpu_ms.end()) stats.gpu_ms.emplace_back(name, ms);
        else same->second += ms;
    }
    if (stale & (kPhotons | kView)) {
        shaders::PhotonStats counters{};
        accum_->stats.read(&counters, sizeof(counters));
        if (stale & kPhotons) {
            stats.photons_entered = counters.photons_entered;
            stats.photon_steps = counters.steps;
            stats.floor_hits = counters.floor_hits;
            stats.direct_overlaps = counters.direct_overlaps;
            stats.photon_scatterings = counters.scatterings;
        }
        if (stale & kView) stats.view_steps = counters.view_steps;
    }
    return stats;
}

PassSet SceneGpu::passes_for(PassSet stale) const {
    if (!(built_ & kToneMap)) stale |= kToneMap;  // a run leaves a whole frame
    if (stale == 0) return 0;
    // The first stale pass runs with what it reads that is not built, and each pass reruns all after it.
    PassSet first = stale & (~stale + 1);
    while (first != kVoxelize && !(built_ & (first >> 1))) first >>= 1;
    return kAllPasses & ~(first - 1);
}

bool SceneGpu::grid_made_for(const protocol::SceneDocument& document, const RunOptions& options) const {
    return options.radiance_factor == radiance_factor_ && options.sampled_deposits == sampled_deposits_ &&
           passes::transport_channels(document) == channels_ &&
           passes::photon_bounces(document, options.bounce_cap) == bounces_;
}

uint32_t SceneGpu::photon_batches(const protocol::SceneDocument& document, const RunOptions& options) const {
    return (built_ & kPhotons) && grid_made_for(document, options) ? photon_batches_ : 0u;
}

RunOptions SceneGpu::with_resident_photons(RunOptions options) const {
    options.radiance_factor = radiance_factor_;
    options.sampled_deposits = sampled_deposits_;
    options.bounce_cap = bounces_;  // the document's bounces capped there are those its photons took
    return options;
}

template <typename T>
std::vector<T> SceneGpu::read_buffer(const vk::Buffer& buffer) const {
    vk::Buffer staging(kit_.context, buffer.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::readback,
                       "readback");
    vk::run_once(kit_.context, [&](vk::CommandRecorder& r) {
        r.copy(buffer, staging, buffer.size());
        r.to_host_barrier();
    });
    std::vector<T> out(buffer.size() / sizeof(T));
    staging.read(out.data(), out.size() * sizeof(T));
    return out;
}

template <typename T>
std::vector<T> SceneGpu::read_image(const vk::Image3D& image) const {
    const VkDeviceSize bytes = image.extent().count() * image.texel_bytes();
    vk::Buffer staging(kit_.context, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::readback, "readback");
    vk::run_once(kit_.context, [&](vk::CommandRecorder& r) {
        r.copy(image, staging);
        r.to_host_barrier();
    });
    std::vector<T> out(bytes / sizeof(T));
    staging.read(out.data(), bytes);
    return out;
}

namespace {
// Half floats (the floor map) widened to float on the host.
std::vector<glm::vec4> widen(const std::vector<uint16_t>& half) {
    std::vector<glm::vec4> out(half.size() / 4);
    for (size_t i = 0; i < out.size(); ++i)
        for (int c = 0; c < 4; ++c) {
            const uint16_t h = half[4 * i + static_cast<size_t>(c)];
            const uint32_t sign = (h & 0x8000u) << 16;
            const uint32_t exponent = (h >> 10) & 0x1fu;
            const uint32_t mantissa = h & 0x3ffu;
            float value;
            if (exponent == 0) value = std::ldexp(static_cast<float>(mantissa), -24);
            else if (exponent == 31) value = mantissa ? std::numeric_limits<float>::quiet_NaN() : std::numeric_limits<float>::infinity();
            else value = std::ldexp(static_cast<float>(mantissa | 0x400u), static_cast<int>(exponent) - 25);
            out[i][c] = sign ? -value : value;
        }
    return out;
}
}  // namespace

template <typename T>
std::vector<T> SceneGpu::on_lattice(const std::vector<T>& texels, T outside) const {
    if (atlas_.dense) return texels;
    std::vector<T> out(grid_.dims.count(), outside);
    for (const FieldAtlas::Cluster& c : atlas_.clusters)
        for (uint32_t z = c.first.z; z < c.end.z; ++z)
            for (uint32_t y = c.first.y; y < c.end.y; ++y)
                for (uint32_t x = c.first.x; x < c.end.x; ++x) {
                    const glm::uvec3 a = glm::uvec3(x, y, z) - c.first + c.atlas_first;
                    out[(size_t{z} * grid_.dims.y + y) * grid_.dims.x + x] =
                        texels[(size_t{a.z} * atlas_.dims.y + a.y) * atlas_.dims.x + a.x];
                }
    return out;
}

std::vector<float> SceneGpu::read_coverage() const {
    const std::vector<glm::vec2> texels = on_lattice(read_image<glm::vec2>(coverage_image_), glm::vec2(0.0f));
    std::vector<float> out(texels.size());
    for (size_t i = 0; i < texels.size(); ++i) out[i] = texels[i].x;
    return out;
}
std::vector<uint32_t> SceneGpu::read_object_numbers() const {
    const std::vector<glm::vec2> texels = on_lattice(read_image<glm::vec2>(coverage_image_), glm::vec2(0.0f));
    std::vector<uint32_t> out(texels.size());
    for (size_t i = 0; i < texels.size(); ++i) out[i] = static_cast<uint32_t>(texels[i].y);
    return out;
}
std::vector<glm::vec4> SceneGpu::read_index_field() const {
    return on_lattice(read_image<glm::vec4>(index_field_), glm::vec4(static_cast<float>(composed_medium_ior_), 0.0f, 0.0f, 0.0f));
}
std::vector<uint32_t> SceneGpu::read_levels() const {
    const std::vector<uint32_t> stored = passes::levels_per_voxel(read_buffer<uint32_t>(levels_), atlas_.dims);
    if (atlas_.dense) return stored;
    // As octree_level() in transport_common.glsl finds them: the map's outside the clusters, the atlas's
    // inside, up to a map cell's.
    std::vector<uint32_t> out(grid_.dims.count());
    for (uint32_t z = 0; z < grid_.dims.z; ++z)
        for (uint32_t y = 0; y < grid_.dims.y; ++y)
            for (uint32_t x = 0; x < grid_.dims.x; ++x) {
                const std::optional<glm::uvec3> a = atlas_.atlas_voxel({x, y, z});
                out[(size_t{z} * grid_.dims.y + y) * grid_.dims.x + x] =
                    a ? std::min(stored[(size_t{a->z} * atlas_.dims.y + a->y) * atlas_.dims.x + a->x], FIELD_CELL_LEVEL)
                      : atlas_.map_entry(glm::uvec3(x, y, z) / FIELD_CELL) - FIELD_EMPTY;
            }
    return out;
}
std::vector<glm::vec2> SceneGpu::read_pyramid() const { return read_buffer<glm::vec2>(pyramid_); }
std::vector<glm::vec4> SceneGpu::read_flux() const { return read_image<glm::vec4>(flux_); }
std::vector<uint32_t> SceneGpu::read_lit_pyramid() const { return read_buffer<uint32_t>(accum_->lit_blocks); }

std::vector<glm::vec4> SceneGpu::read_radiance() const {
    if (!grey()) return read_image<glm::vec4>(radiance_);
    // Grey transport: the light's colour times the channels' mean, as the viewing pass shades it.
    const glm::vec3 colour = shaders::grey_colour(params().photon_flux);
    std::vector<glm::vec4> out = read_flux();
    for (glm::vec4& v : out) v = glm::vec4(colour * v.w, 0.0f);
    return out;
}
std::vector<glm::vec4> SceneGpu::read_floor_map() const { return widen(read_image<uint16_t>(floor_map_)); }

std::vector<glm::vec4> SceneGpu::read_floor_irradiance() const {
    std::vector<glm::vec4> map = read_floor_map();
    const auto& p = params();
    const float texel = p.floor_map.z / static_cast<float>(floor_texels_);
    for (uint32_t j = 0; j < floor_texels_; ++j)
        for (uint32_t i = 0; i < floor_texels_; ++i) {
            const glm::vec3 x(p.floor_map.x + (static_cast<float>(i) + 0.5f) * texel, p.floor_plane.x,
                              p.floor_map.y + (static_cast<float>(j) + 0.5f) * texel);
            // Mirrors direct_irradiance() in shaders/view.comp.
            glm::vec3 direct(0.0f);
            for (uint32_t k = 0; k < p.light_set.x; ++k) {
                const shaders::LightParams& light = p.lights[k];
                if (light.type.x == LIGHT_DIRECTIONAL) {
                    direct += glm::vec3(light.power) * std::max(0.0f, -light.direction.y);
                    continue;
                }
                const glm::vec3 l = glm::vec3(light.position) - x;
                const float r2 = glm::dot(l, l);
                const glm::vec3 to_light = l / std::sqrt(r2);
                const bool in_cone = light.type.x != LIGHT_SPOT ||
                                     glm::dot(-to_light, glm::vec3(light.direction)) >= light.position.w;
                if (in_cone) direct += glm::vec3(light.power) * std::max(0.0f, to_light.y) / r2;
            }
            direct += glm::vec3(p.environment_light);
            glm::vec4& texel_value = map[size_t{j} * floor_texels_ + i];
            texel_value = glm::vec4(glm::max(glm::vec3(texel_value) + direct, glm::vec3(0.0f)), 0.0f);
        }
    return map;
}

std::vector<glm::vec4> SceneGpu::read_hdr() const {
    std::vector<glm::vec4> out(size_t{width_} * height_);
    hdr_.read(out.data(), out.size() * sizeof(glm::vec4));
    return out;
}

std::vector<uint32_t> SceneGpu::read_ldr() const {
    std::vector<uint32_t> out(size_t{width_} * height_);
    ldr_.read(out.data(), out.size() * sizeof(uint32_t));
    return out;
}

std::vector<shaders::PhotonExit> SceneGpu::read_photon_exits() const {
    std::vector<shaders::PhotonExit> out(exit_capacity_);
    accum_->exits.read(out.data(), out.size() * sizeof(shaders::PhotonExit));
    return out;
}

}  // namespace refract::scene
