#include "render/volume_stage.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string_view>

#include "assets/render_error.h"
#include "passes/octree.h"
#include "render/read_back.h"

namespace refract::scene {

FieldAtlas field_atlas_for(const passes::GridGeometry& lattice, const std::map<std::string, passes::ObjectBox>& boxes,
                           bool dense, uint32_t max_side) {
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

std::vector<glm::vec4> bending_spheres(const passes::GridGeometry& lattice, const FrameInputs::Volume& in,
                                       const WorldMeshes& worlds) {
    const float apron = static_cast<float>(object_apron(in.smoothing)) * lattice.voxel_size;
    std::vector<glm::vec4> spheres;
    for (const auto& [name, world] : worlds) {
        if (world.positions.empty()) continue;
        const mesh::Bounds box = mesh::bounds(world);
        const glm::vec3 centre = 0.5f * (box.min + box.max);
        float radius = 0.0f;
        for (const glm::vec3& p : world.positions) radius = std::max(radius, glm::length(p - centre));
        spheres.emplace_back(centre, radius + apron);
    }
    for (const auto& [name, shape] : in.objects)
        if (shape.kind == INDEX_KIND_LUNEBURG || shape.kind == INDEX_KIND_MAXWELL)
            spheres.emplace_back(glm::vec3(shape.sphere), shape.sphere.w + apron);
    return spheres;
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

constexpr auto kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                          VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
}  // namespace

VolumeStage::VolumeStage(PassKit& kit) : kit_(kit) {}

void VolumeStage::clear() {
    // Drop the old volume first so peak memory is one volume, not two.
    objects_.clear();
    bending_.clear();
    pyramid_ = {};
    levels_ = {};
    index_field_ = {};
    coverage_image_ = {};
    atlas_ = {};
}

bool VolumeStage::lay_out(const passes::GridGeometry& lattice, const FrameInputs::Volume& in, const WorldMeshes& worlds,
                          PassSet stale, PassSet built) {
    lattice_ = lattice;
    field_fresh_ = false;
    boxes_.clear();
    if (!(stale & kVoxelize)) return false;
    if (!in.imported) boxes_ = object_boxes(lattice_, worlds, in.smoothing);
    bending_ = in.imported ? std::vector<glm::vec4>{} : bending_spheres(lattice_, in, worlds);
    FieldAtlas layout = field_atlas_for(lattice_, boxes_, in.imported || in.objects.size() < 2,
                                        kit_.context.limits().maxImageDimension3D);
    if (layout == atlas_ && index_field_.get()) return false;
    // A new layout of an atlas built before carries the clusters that stay over from the old images
    // (held until the submission completes), so that an edit of one object composes that one's cluster.
    if ((built & kIndexField) && !atlas_.dense && !layout.dense) {
        carried_.index_field = std::move(index_field_);
        carried_.coverage = std::move(coverage_image_);
        carried_.atlas = atlas_;
    }
    allocate_field(std::move(layout));
    field_fresh_ = true;
    return true;
}

void VolumeStage::allocate_field(FieldAtlas atlas) {
    vk::Context& ctx = kit_.context;
    pyramid_ = {};
    levels_ = {};
    index_field_ = {};
    coverage_image_ = {};
    index_field_ = vk::Image3D(ctx, atlas.dims, VK_FORMAT_R32G32B32A32_SFLOAT, "index field");
    coverage_image_ = vk::Image3D(ctx, atlas.dims, VK_FORMAT_R32G32_SFLOAT, "coverage and object image");
    const passes::OctreeLayout octree = passes::octree_layout(atlas.dims);
    pyramid_ = vk::Buffer(ctx, std::max<uint64_t>(octree.node_count, 1) * 2 * sizeof(float), kStorage,
                          vk::MemoryUse::device, "octree pyramid");
    levels_ = vk::Buffer(ctx, octree.cell_count * sizeof(uint32_t), kStorage, vk::MemoryUse::device, "octree levels");
    atlas_map_ = {};
    if (!atlas.dense) {
        atlas_map_ = vk::Buffer(ctx, std::max<size_t>(atlas.map.size(), 1) * sizeof(uint32_t),
                                VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, vk::MemoryUse::upload, "field atlas map");
        atlas_map_.write(atlas.map.data(), atlas.map.size() * sizeof(uint32_t));
    }
    atlas_ = std::move(atlas);
}

bool VolumeStage::record(FrameRecording& recording, PassSet stale, PassSet built, const FrameInputs::Volume& in,
                         const WorldMeshes& worlds, const IndexGrid* grid_asset, const VoxelizeOptions& voxelize,
                         std::vector<std::string>& voxelized) {
    // Grid values for the index-field pass: the imported field, or a placeholder it never reads.
    if (stale & kIndexField) {
        const uint64_t count = in.imported ? lattice_.dims.count() : 1;
        grid_values_ = vk::Buffer(kit_.context, count * sizeof(float), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                  vk::MemoryUse::upload, "imported index grid");
        if (in.imported) grid_values_.write(grid_asset->n.data(), count * sizeof(float));
    }
    vk::CommandRecorder& recorder = recording.recorder();
    if (field_fresh_) {
        for (const vk::Image3D* image : {&index_field_, &coverage_image_}) recorder.init_image(*image);
    }
    field_changed_ = {glm::uvec3(0u), glm::uvec3(atlas_.dims.x, atlas_.dims.y, atlas_.dims.z)};
    moved_ = {};
    if (stale & kVoxelize) {
        recording.begin(kVoxelize);
        record_voxelize(recorder, in, worlds, grid_asset, voxelize, voxelized);
        recorder.compute_barrier();
        recording.end();
        if ((stale & kIndexField) && recording.part(kIndexField)) return false;
    }
    if (stale & kIndexField) {
        recording.begin(kIndexField);
        record_index_field(recorder, in, (built & kIndexField) || carried_.index_field.get());
        recorder.compute_barrier();
        recording.end();
        if ((stale & kOctree) && recording.part(kOctree)) return false;
    }
    if (stale & kOctree) {
        recording.begin(kOctree);
        // Over what the changed voxels reach, when the resident octree is the old field's at this epsilon.
        const bool resident = (built & kOctree) && in.octree_epsilon == octree_epsilon_;
        const passes::VoxelRange whole_field{glm::uvec3(0u), glm::uvec3(atlas_.dims.x, atlas_.dims.y, atlas_.dims.z)};
        kit_.octree.record(recorder, index_field_, in.octree_epsilon, resident ? field_changed_ : whole_field, pyramid_,
                           levels_);
        octree_epsilon_ = in.octree_epsilon;
        recorder.compute_barrier();
        recording.end();
        if ((stale & kPhotons) && recording.part(kPhotons)) return false;
    }
    return true;
}

void VolumeStage::end_run() {
    carried_.index_field = {};
    carried_.coverage = {};
    carried_.atlas = {};
    uploads_.clear();
    scratch_.clear();
    coverage_upload_ = {};
    zeros_ = {};
}

void VolumeStage::record_imported(vk::CommandRecorder& recorder, const FrameInputs::Volume& in,
                                  const IndexGrid& grid_asset) {
    ObjectVolume& volume = objects_[in.objects.front().first];
    volume.box = {lattice_, glm::uvec3(0u)};
    volume.coverage = vk::Buffer(kit_.context, lattice_.dims.count() * sizeof(float), kStorage, vk::MemoryUse::device,
                                 "coverage");
    // An imported field has no mesh: coverage is where n departs from the medium.
    std::vector<float> coverage(lattice_.dims.count());
    float n_max = static_cast<float>(in.medium_ior);
    for (float n : grid_asset.n) n_max = std::max(n_max, n);
    const float span = std::max(n_max - static_cast<float>(in.medium_ior), 1e-6f);
    for (size_t i = 0; i < coverage.size(); ++i)
        coverage[i] = std::clamp((grid_asset.n[i] - static_cast<float>(in.medium_ior)) / span, 0.0f, 1.0f);
    coverage_upload_ = vk::Buffer(kit_.context, coverage.size() * sizeof(float), VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                  vk::MemoryUse::upload, "coverage upload");
    coverage_upload_.write(coverage.data(), coverage.size() * sizeof(float));
    recorder.copy(coverage_upload_, volume.coverage, coverage.size() * sizeof(float));
}

void VolumeStage::record_voxelize(vk::CommandRecorder& recorder, const FrameInputs::Volume& in,
                                  const WorldMeshes& worlds, const IndexGrid* grid_asset,
                                  const VoxelizeOptions& options, std::vector<std::string>& voxelized) {
    std::erase_if(objects_, [&](const auto& held) {
        return std::none_of(in.objects.begin(), in.objects.end(), [&](const auto& o) { return o.first == held.first; });
    });
    if (in.imported) {
        record_imported(recorder, in, *grid_asset);
        voxelized.push_back(in.objects.front().first);
        return;
    }
    // Only the objects whose coverage no longer fits their world mesh, box, smoothing or rays.
    for (const auto& [name, box] : boxes_) {
        const mesh::Mesh& world = worlds.at(name);
        const size_t hash = mesh_hash(world);
        auto held = objects_.find(name);
        if (!options.again && held != objects_.end() && held->second.mesh_hash == hash &&
            held->second.smoothing == in.smoothing && held->second.subsamples == options.subsamples &&
            held->second.box.box == box.box)
            continue;
        if (held != objects_.end()) moved_ = joined(moved_, range_of(held->second.box));
        moved_ = joined(moved_, range_of(box));
        ObjectVolume& volume = objects_[name];
        volume.box = box;
        volume.mesh_hash = hash;
        volume.smoothing = in.smoothing;
        volume.subsamples = options.subsamples;
        voxelized.push_back(name);
        if (box.empty()) continue;  // outside the lattice: nothing to voxelize
        const VkDeviceSize bytes = box.box.dims.count() * sizeof(float);
        if (!volume.coverage.get() || volume.coverage.size() != bytes)
            volume.coverage = vk::Buffer(kit_.context, bytes, kStorage, vk::MemoryUse::device, "coverage");
        scratch_.emplace_back(kit_.context, bytes, kStorage, vk::MemoryUse::device, "coverage scratch");
        uploads_.push_back(kit_.voxelize.record(recorder, world, box.box, static_cast<float>(in.smoothing),
                                                scratch_.back(), volume.coverage, options.subsamples));
    }
}

passes::VoxelRange VolumeStage::recompose_region(const FrameInputs::Volume& in, bool resident) const {
    // The whole lattice, unless the field of these very objects (by name, so by number) over this medium
    // is resident and only some objects moved or changed their field: then their boxes.
    const passes::VoxelRange whole{glm::uvec3(0u), glm::uvec3(lattice_.dims.x, lattice_.dims.y, lattice_.dims.z)};
    const bool same_objects = std::equal(composed_objects_.begin(), composed_objects_.end(), in.objects.begin(),
                                         in.objects.end(), [](const auto& a, const auto& b) { return a.first == b.first; });
    if (in.objects.size() < 2 || !resident || !same_objects || composed_medium_ior_ != in.medium_ior) return whole;
    passes::VoxelRange region = moved_;
    for (size_t i = 0; i < in.objects.size(); ++i)
        if (!(composed_objects_[i].second == in.objects[i].second))
            region = joined(region, range_of(objects_.at(in.objects[i].first).box));
    return region;
}

void VolumeStage::record_index_field(vk::CommandRecorder& recorder, const FrameInputs::Volume& in, bool resident) {
    const bool several = in.objects.size() > 1;
    std::vector<passes::ObjectField> fields;
    uint32_t number = 0;
    for (const auto& [name, shape] : in.objects) {
        const ObjectVolume& volume = objects_.at(name);
        ++number;
        if (!volume.box.empty())
            fields.push_back({shape, volume.box.box, volume.box.offset, volume.coverage, several ? number : 0u});
    }
    passes::VoxelRange region = recompose_region(in, resident);
    // New atlas images, or a field composed whole, start as the medium everywhere, the room between
    // the clusters too (the octree's ranges read a voxel past a cluster's edge, as in the lattice).
    const bool whole = region.first == glm::uvec3(0u) &&
                       region.end == glm::uvec3(lattice_.dims.x, lattice_.dims.y, lattice_.dims.z);
    const bool cleared = !atlas_.dense && (field_fresh_ || whole);
    if (cleared) {
        recorder.clear(index_field_, {static_cast<float>(in.medium_ior), 0.0f, 0.0f, 0.0f});
        recorder.clear(coverage_image_, {0.0f, 0.0f, 0.0f, 0.0f});
        recorder.compute_barrier();
    }
    // The clusters that stay are copied across; the others are composed anew, whole.
    if (carried_.index_field.get() && !whole) {
        for (const FieldAtlas::Cluster& c : atlas_.clusters) {
            const auto was = std::find_if(carried_.atlas.clusters.begin(), carried_.atlas.clusters.end(),
                                          [&](const FieldAtlas::Cluster& o) { return o.first == c.first && o.end == c.end; });
            if (was == carried_.atlas.clusters.end()) {
                region = joined(region, {c.first, c.end});
                continue;
            }
            const glm::uvec3 e = c.extent();
            for (const auto& [from, to] : {std::pair{&carried_.index_field, &index_field_}, std::pair{&carried_.coverage, &coverage_image_}})
                recorder.copy(*from, {was->atlas_first.x, was->atlas_first.y, was->atlas_first.z}, *to,
                              {c.atlas_first.x, c.atlas_first.y, c.atlas_first.z}, {e.x, e.y, e.z});
        }
        recorder.compute_barrier();
    }
    std::vector<passes::FieldBlock> blocks;
    for (const FieldAtlas::Cluster& c : atlas_.clusters) blocks.push_back({{c.first, c.end}, c.atlas_first});
    if (several && !region.empty() && !cleared) {
        zeros_ = vk::Buffer(kit_.context, std::max<uint64_t>(passes::largest_part(blocks, region), 1) * sizeof(float),
                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::device,
                            "medium coverage");
        recorder.fill(zeros_, 0u);
        recorder.transfer_to_compute_barrier();
    }
    field_changed_ = {};
    if (!region.empty())
        field_changed_ = kit_.index_field.record(recorder, in.medium, lattice_, fields, blocks, region,
                                                 cleared ? nullptr : (several ? &zeros_ : &grid_values_), grid_values_,
                                                 index_field_, coverage_image_);
    composed_objects_ = in.objects;
    composed_medium_ior_ = in.medium_ior;
}

template <typename T>
std::vector<T> VolumeStage::on_lattice(const std::vector<T>& texels, T outside) const {
    if (atlas_.dense) return texels;
    std::vector<T> out(lattice_.dims.count(), outside);
    for (const FieldAtlas::Cluster& c : atlas_.clusters)
        for (uint32_t z = c.first.z; z < c.end.z; ++z)
            for (uint32_t y = c.first.y; y < c.end.y; ++y)
                for (uint32_t x = c.first.x; x < c.end.x; ++x) {
                    const glm::uvec3 a = glm::uvec3(x, y, z) - c.first + c.atlas_first;
                    out[(size_t{z} * lattice_.dims.y + y) * lattice_.dims.x + x] =
                        texels[(size_t{a.z} * atlas_.dims.y + a.y) * atlas_.dims.x + a.x];
                }
    return out;
}

std::vector<float> VolumeStage::read_coverage() const {
    const std::vector<glm::vec2> texels = on_lattice(read_image<glm::vec2>(kit_.context, coverage_image_), glm::vec2(0.0f));
    std::vector<float> out(texels.size());
    for (size_t i = 0; i < texels.size(); ++i) out[i] = texels[i].x;
    return out;
}

std::vector<uint32_t> VolumeStage::read_object_numbers() const {
    const std::vector<glm::vec2> texels = on_lattice(read_image<glm::vec2>(kit_.context, coverage_image_), glm::vec2(0.0f));
    std::vector<uint32_t> out(texels.size());
    for (size_t i = 0; i < texels.size(); ++i) out[i] = static_cast<uint32_t>(texels[i].y);
    return out;
}

std::vector<glm::vec4> VolumeStage::read_index_field() const {
    return on_lattice(read_image<glm::vec4>(kit_.context, index_field_),
                      glm::vec4(static_cast<float>(composed_medium_ior_), 0.0f, 0.0f, 0.0f));
}

std::vector<uint32_t> VolumeStage::read_levels() const {
    const std::vector<uint32_t> stored = passes::levels_per_voxel(read_buffer<uint32_t>(kit_.context, levels_), atlas_.dims);
    if (atlas_.dense) return stored;
    // As octree_level() in transport_common.glsl finds them: the map's outside the clusters, the atlas's
    // inside, up to a map cell's.
    std::vector<uint32_t> out(lattice_.dims.count());
    for (uint32_t z = 0; z < lattice_.dims.z; ++z)
        for (uint32_t y = 0; y < lattice_.dims.y; ++y)
            for (uint32_t x = 0; x < lattice_.dims.x; ++x) {
                const std::optional<glm::uvec3> a = atlas_.atlas_voxel({x, y, z});
                out[(size_t{z} * lattice_.dims.y + y) * lattice_.dims.x + x] =
                    a ? std::min(stored[(size_t{a->z} * atlas_.dims.y + a->y) * atlas_.dims.x + a->x], FIELD_CELL_LEVEL)
                      : atlas_.map_entry(glm::uvec3(x, y, z) / FIELD_CELL) - FIELD_EMPTY;
            }
    return out;
}

std::vector<glm::vec2> VolumeStage::read_pyramid() const { return read_buffer<glm::vec2>(kit_.context, pyramid_); }

}  // namespace refract::scene
