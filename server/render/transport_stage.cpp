#include "render/transport_stage.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "assets/render_error.h"
#include "passes/transport_params.h"
#include "render/read_back.h"
#include "render/scene_gpu.h"

namespace refract::scene {

namespace {
glm::uvec2 halves(VkDeviceAddress a) { return glm::uvec2(static_cast<uint32_t>(a), static_cast<uint32_t>(a >> 32)); }
}  // namespace

TransportStage::TransportStage(PassKit& kit) : kit_(kit) {}

void TransportStage::clear() {
    accum_.reset();
    radiance_ = {};
    flux_ = {};
    floor_map_ = {};
    raw_radiance_ = {};
    raw_flux_ = {};
    raw_floor_map_ = {};
}

bool TransportStage::made_for(const FrameInputs::Transport& in, const RunOptions& options) const {
    return options.radiance_factor == radiance_factor_ && options.sampled_deposits == sampled_deposits_ &&
           options.adaptive_density == adaptive_density_ && in.channels == channels_ && in.bounces == bounces_;
}

void TransportStage::make_for(const FrameInputs::Transport& in, const RunOptions& options) {
    sampled_deposits_ = options.sampled_deposits;
    adaptive_density_ = options.adaptive_density;
    bounces_ = in.bounces;
}

RunOptions TransportStage::with_resident_photons(RunOptions options) const {
    options.radiance_factor = radiance_factor_;
    options.sampled_deposits = sampled_deposits_;
    options.adaptive_density = adaptive_density_;
    options.bounce_cap = bounces_;  // the document's bounces capped there are those its photons took
    return options;
}

void TransportStage::prepare_environment(const passes::EnvironmentSource& source) {
    if (environment_map_.get() && environment_source_ == source) return;
    if (source.kind == passes::EnvironmentSource::Kind::image && source.image == nullptr)
        throw RenderError("environment image '" + source.name + "' is not loaded");
    environment_light_ = passes::make_environment_light(source);
    const uint64_t bytes = environment_light_.texels.size() * sizeof(glm::vec4);
    environment_map_ = {};
    environment_map_ = vk::Buffer(kit_.context, bytes, VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, vk::MemoryUse::upload,
                                  "environment map");
    environment_map_.write(environment_light_.texels.data(), bytes);
    environment_light_.texels = {};  // the device holds the map; a large one is not kept twice
    environment_source_ = source;
}

void TransportStage::allocate(const passes::GridGeometry& lattice, uint32_t photon_exit_count, bool record_exits,
                              uint32_t radiance_factor, uint32_t channels, bool adaptive_density) {
    vk::Context& ctx = kit_.context;
    const bool to_grey = channels == CHANNELS_GREY;
    const uint32_t floor_texels = passes::floor_map_texels(lattice);
    const uint32_t exits = record_exits ? photon_exit_count : 1u;
    const uint32_t f = radiance_factor;
    const vk::Extent3 radiance_dims = lattice.coarsened(f * lattice.light_factor);
    if (!accum_ || floor_texels != floor_texels_ || exits != exit_capacity_ || f != radiance_factor_ ||
        to_grey != grey()) {
        accum_.reset();
        accum_.emplace(passes::make_photon_accumulators(ctx, radiance_dims, floor_texels,
                                                        passes::light_map_capacity(lattice), exits, to_grey));
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
    // The resolve's own images, for the spread to read, and the spread's shares, at the same sizes.
    if (!adaptive_density) {
        raw_flux_ = {};
        raw_radiance_ = {};
        flux_shares_ = {};
        radiance_shares_ = {};
    } else if (!raw_flux_.get() || !(raw_flux_.extent() == radiance_dims) || !(raw_radiance_.extent() == colour_dims)) {
        raw_flux_ = {};
        raw_radiance_ = {};
        flux_shares_ = {};
        radiance_shares_ = {};
        raw_flux_ = vk::Image3D(ctx, radiance_dims, VK_FORMAT_R32G32B32A32_SFLOAT, "resolved flux before the spread");
        raw_radiance_ = vk::Image3D(ctx, colour_dims, VK_FORMAT_R32G32B32A32_SFLOAT, "resolved radiance before the spread");
        flux_shares_ = vk::Image3D(ctx, radiance_dims, VK_FORMAT_R32G32B32A32_SFLOAT, "spread flux shares");
        radiance_shares_ = vk::Image3D(ctx, colour_dims, VK_FORMAT_R32G32B32A32_SFLOAT, "spread radiance shares");
    }
    const uint64_t floor_bytes = uint64_t{floor_texels} * floor_texels * 4 * sizeof(uint16_t);
    if (floor_texels != floor_texels_ || !floor_map_.get()) {
        floor_map_ = {};
        floor_map_ = vk::Buffer(ctx, floor_bytes,
                                VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                vk::MemoryUse::device, "floor caustic map");
        floor_texels_ = floor_texels;
    }
    if (!adaptive_density) {
        raw_floor_map_ = {};
        floor_spread_sums_ = {};
    } else if (!raw_floor_map_.get() || raw_floor_map_.size() != floor_bytes) {
        raw_floor_map_ = {};
        floor_spread_sums_ = {};
        raw_floor_map_ = vk::Buffer(ctx, floor_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                    vk::MemoryUse::device, "floor map before the spread");
        floor_spread_sums_ =
            vk::Buffer(ctx, passes::floor_spread_bytes(floor_texels), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                       vk::MemoryUse::device, "floor map spread sums");
    }
}

void TransportStage::prepare_medium_field(const std::map<std::string, protocol::DensityVolume>& volumes,
                                          const passes::GridGeometry& lattice, const Densities& densities) {
    uploaded_field_.reset();  // the run that copied it has ended
    // Without volumes the field is one brick of zeros whatever the lattice, so the passes always bind it.
    FieldSource source{volumes.empty() ? passes::GridGeometry{} : lattice, volumes, {}};
    for (const auto& [name, member] : volumes) {
        const auto it = densities.find(name);
        if (it != densities.end()) source.densities.emplace(name, it->second);
    }
    if (field_source_ == source) return;
    const MediumField field = resample_volumes(lattice, volumes, densities);
    const vk::Extent3 atlas{field.layout.bricks.x * kMediumBrickSide, field.layout.bricks.y * kMediumBrickSide,
                            field.layout.bricks.z * kMediumBrickSide};
    const std::vector<glm::vec4> no_emission(field.emission.empty() ? 1 : 0, glm::vec4(0.0f));
    const std::vector<glm::vec4>& emission = field.emission.empty() ? no_emission : field.emission;
    auto image = [&](vk::Image3D& target, vk::Extent3 dims, const char* name) {
        target = {};
        target = vk::Image3D(kit_.context, dims, VK_FORMAT_R32G32B32A32_SFLOAT, name);
    };
    image(medium_extinction_, atlas, "medium field extinction bricks");
    image(medium_scattering_, atlas, "medium field scattering bricks");
    image(medium_emission_, field.emission.empty() ? vk::Extent3{1, 1, 1} : atlas, "medium field emission bricks");
    auto staged = [&](const std::vector<glm::vec4>& texels, const char* name) {
        const uint64_t bytes = texels.size() * sizeof(glm::vec4);
        vk::Buffer buffer(kit_.context, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::upload, name);
        buffer.write(texels.data(), bytes);
        return buffer;
    };
    field_upload_.emplace(FieldUpload{staged(field.extinction, "medium field extinction upload"),
                                      staged(field.scattering, "medium field scattering upload"),
                                      staged(emission, "medium field emission upload")});
    // Read by the passes through their addresses: written here, as the materials are.
    auto addressed = [&](vk::Buffer& target, std::vector<glm::uvec2> entries, const char* name) {
        if (entries.empty()) entries.assign(1, glm::uvec2(MEDIUM_NO_BRICK, 0u));
        target = {};
        target = vk::Buffer(kit_.context, entries.size() * sizeof(glm::uvec2), VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT,
                            vk::MemoryUse::upload, name);
        target.write(entries.data(), entries.size() * sizeof(glm::uvec2));
    };
    addressed(medium_blocks_, field.blocks, "medium field blocks");
    addressed(medium_emitters_, field.emitters, "medium field emitters");
    field_layout_ = field.layout;
    emitter_count_ = static_cast<uint32_t>(field.emitters.size());
    emitted_ = field.emitted;
    field_source_ = std::move(source);
}

void TransportStage::prepare(const FrameInputs::Transport& in, PassSet stale, const RunOptions& options,
                             const passes::GridGeometry& lattice, const VolumeStage& volume) {
    light_params_ = in.lights;
    // Several objects: their materials, by the object numbers the index field holds per voxel.
    const bool several = !in.materials.empty();
    if (several) {
        if (!materials_.get())  // room for the most objects a scene may hold
            materials_ = vk::Buffer(kit_.context, sizeof(shaders::Material) * protocol::kMaxObjects,
                                    VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, vk::MemoryUse::upload, "object materials");
        materials_.write(in.materials.data(), in.materials.size() * sizeof(shaders::Material));
    }
    uint32_t most_photons = 0;  // of one light's dispatch (with the environment's, for the first)
    for (const auto& light : light_params_) most_photons = std::max(most_photons, light.photon_info.x);
    if (stale & kPhotons)
        allocate(lattice, passes::photon_exit_count(most_photons, in.channels), options.record_photon_exits,
                 options.radiance_factor, in.channels, options.adaptive_density);
    while (params_buffers_.size() < light_params_.size())
        params_buffers_.emplace_back(kit_.context, sizeof(shaders::TransportParams), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                     vk::MemoryUse::upload, "transport params");
    const FieldAtlas& atlas = volume.atlas();
    for (size_t i = 0; i < light_params_.size(); ++i) {
        shaders::TransportParams& params = light_params_[i];
        params.flags.x = options.record_photon_exits ? 1u : 0u;
        if (accum_) params.radiance_sums = glm::uvec4(halves(accum_->red_green.address()), halves(accum_->flux.address()));
        params.environment_map = glm::uvec4(halves(environment_map_.address()), 0u, 0u);
        if (several) params.materials = glm::uvec4(halves(materials_.address()), params.materials.z, 0u);
        if (!atlas.dense) params.field_atlas = glm::uvec4(halves(volume.atlas_map().address()), 0u, 0u);
        params.atlas_dims = glm::uvec4(atlas.dims.x, atlas.dims.y, atlas.dims.z, 0u);
        params.volume_emission = glm::uvec4(params.volume_emission.x, emitter_count_, halves(medium_emitters_.address()));
        const vk::Extent3& dims = field_layout_.dims;
        params.medium_field = glm::vec4(static_cast<float>(dims.x), static_cast<float>(dims.y), static_cast<float>(dims.z),
                                        static_cast<float>(field_layout_.step));
        params.medium_blocks = glm::uvec4(halves(medium_blocks_.address()), field_layout_.bricks.x, field_layout_.bricks.y);
        params_buffers_[i].write(&params, sizeof(params));
    }
    const shaders::TransportParams& first = light_params_.front();
    // A fade thins only the medium's coefficients: where they are 0 it changes nothing.
    const bool medium = glm::any(glm::greaterThan(glm::vec3(first.medium_extinction) + glm::vec3(first.medium_scattering),
                                                  glm::vec3(0.0f)));
    variant_ = {channels_, first.flags.y == COVERAGE_FETCH || first.flags.z == COVERAGE_FETCH, in.fresnel, in.film,
                several, !atlas.dense, !in.volumes.empty(), medium && first.medium_fade.x > 0.0f};
}

passes::TransportInputs TransportStage::inputs_for(const vk::Buffer& params, const VolumeStage& volume) const {
    return passes::TransportInputs{params,
                                   volume.index_field(),
                                   volume.coverage_image(),
                                   volume.levels(),
                                   medium_extinction_,
                                   medium_scattering_,
                                   medium_emission_,
                                   variant_};
}

passes::TransportInputs TransportStage::view_inputs(const VolumeStage& volume) const {
    return inputs_for(params_buffer(), volume);
}

bool TransportStage::record(FrameRecording& recording, PassSet stale, PassSet built, const RunOptions& options,
                            const passes::GridGeometry& lattice, const VolumeStage& volume, bool& resolved) {
    vk::CommandRecorder& recorder = recording.recorder();
    if (field_upload_) {
        // A new medium field: its images into the layout the passes sample, filled before any pass reads.
        for (const auto& [staging, image] : {std::pair{&field_upload_->extinction, &medium_extinction_},
                                             std::pair{&field_upload_->scattering, &medium_scattering_},
                                             std::pair{&field_upload_->emission, &medium_emission_}}) {
            recorder.init_image(*image);
            recorder.copy(*staging, *image);
        }
        recorder.transfer_to_compute_barrier();
        uploaded_field_ = std::move(field_upload_);
        field_upload_.reset();
    }
    if (stale & kPhotons && !(built & kPhotons)) {
        for (const vk::Image3D* image :
             {&radiance_, &flux_, &raw_radiance_, &raw_flux_, &radiance_shares_, &flux_shares_})
            if (image->get()) recorder.init_image(*image);
    }
    if (!(stale & kPhotons)) return true;
    recording.begin(kPhotons);
    passes::clear_photon_accumulators(recorder, *accum_, grey());
    // Light by light: each one's sums hold its own unbent light (transport.h), so each is resolved into
    // the radiance grid and floor map, the first replacing this batch's share and the rest adding theirs.
    // A refinement step gives way after the direct light and after each resolve but the last too (each a
    // tenth of a second or more on two cores), not only between parts of the photons. After the last
    // light's resolve the grid holds the whole batch, and the step goes on to its view's first chance,
    // where the batch is kept: given way there, a batch in the grid but not counted whole was traced anew
    // by the frame after it, a drag that interrupted it shading from its own few photons.
    const passes::BetweenParts gap = recording.between_parts(kPhotons);
    const uint32_t radiance_factor = options.radiance_factor * lattice.light_factor;
    for (size_t i = 0; i < light_params_.size(); ++i) {
        const shaders::TransportParams& light = light_params_[i];
        const passes::TransportInputs light_inputs = inputs_for(params_buffers_[i], volume);
        if (i > 0) passes::clear_for_next_light(recorder, *accum_, grey());
        if (light.direct_light.w > 0.5f) {
            kit_.direct_light.record(recorder, light_inputs, *accum_, static_cast<uint32_t>(light.direct_light.x),
                                     lattice.coarsened(radiance_factor));
            recorder.compute_barrier();
            if (gap && gap()) return false;
        } else if (light.direct_light.z > 0.5f) {
            kit_.direct_light.record_floor_shadow(recorder, light_inputs, *accum_,
                                                  static_cast<uint32_t>(light.direct_light.x));
            recorder.compute_barrier();
        }
        if (!kit_.photon_trace.record(recorder, light_inputs, *accum_, light.photon_info.x, options.sampled_deposits,
                                      bounces_ > 0, recording.between_parts(kPhotons),
                                      photon_parts_.paced(options.paced_parts)))
            return false;
        recorder.compute_barrier();
        const bool spread = raw_flux_.get() != VK_NULL_HANDLE;
        kit_.radiance_resolve.record(recorder, params_buffers_[i], *accum_, grey(),
                                     spread ? raw_radiance_ : radiance_, spread ? raw_flux_ : flux_,
                                     spread ? raw_floor_map_ : floor_map_, floor_texels_,
                                     !spread && i + 1 == light_params_.size());
        resolved = true;
        recorder.compute_barrier();
        if (i + 1 < light_params_.size() && gap && gap()) return false;
    }
    if (raw_flux_.get()) {
        kit_.radiance_spread.record(recorder, params_buffer(), grey(),
                                    {raw_radiance_, raw_flux_, raw_floor_map_, floor_texels_},
                                    {radiance_shares_, flux_shares_, floor_spread_sums_},
                                    {radiance_, flux_, floor_map_, floor_texels_}, accum_->floor_shadow);
        recorder.compute_barrier();
    }
    recording.end();
    photon_batches_ = options.photon_batch + 1;
    return !((stale & kView) && recording.part(kView));
}

std::vector<glm::vec4> TransportStage::read_flux() const { return read_image<glm::vec4>(kit_.context, flux_); }

std::vector<glm::vec4> TransportStage::read_radiance() const {
    if (!grey()) return read_image<glm::vec4>(kit_.context, radiance_);
    // Grey transport: the light's colour times the channels' mean, as the viewing pass shades it.
    const glm::vec3 colour = shaders::grey_colour(light_params_.front().photon_flux);
    std::vector<glm::vec4> out = read_flux();
    for (glm::vec4& v : out) v = glm::vec4(colour * v.w, 0.0f);
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

std::vector<glm::vec4> TransportStage::read_floor_map() const {
    return widen(read_buffer<uint16_t>(kit_.context, floor_map_));
}

namespace {
// What the medium lets through along the straight segment from world point x along unit d for `distance`
// metres, as medium_transmittance() in shaders/shared/transport_common.glsl takes it, but by the midpoint
// rule over the density (medium_density) rather than its closed-form integral: an independent check.
glm::vec3 medium_transmittance(const shaders::TransportParams& p, glm::vec3 x, glm::vec3 d, float distance) {
    const glm::vec3 extinction(p.medium_extinction);
    if (extinction == glm::vec3(0.0f)) return glm::vec3(1.0f);
    const float h = p.grid_origin.w;
    const glm::vec3 dims(p.grid_dims);
    const glm::vec3 q = (x - glm::vec3(p.grid_origin)) / h;
    const glm::vec3 t0 = (glm::vec3(0.0f) - q) / d, t1 = (dims - q) / d;
    const glm::vec3 lo = glm::min(t0, t1), hi = glm::max(t0, t1);
    const float enter = std::max({lo.x, lo.y, lo.z, 0.0f});
    const float leave = std::min({hi.x, hi.y, hi.z, distance / h});
    if (leave <= enter) return glm::vec3(1.0f);
    const glm::vec3 low_faces(0.0f, p.medium_fade.y, 0.0f);
    const auto density = [&](glm::vec3 v) {
        if (p.medium_fade.x <= 0.0f) return 1.0f;
        const glm::vec3 nearest = glm::min(v - low_faces, dims - v);
        const float u = std::clamp(std::min({nearest.x, nearest.y, nearest.z}) * p.medium_fade.z, 0.0f, 1.0f);
        return u * u * (3.0f - 2.0f * u);
    };
    constexpr int kSteps = 256;
    const float step = (leave - enter) / kSteps;
    double depth = 0.0;  // voxels at full density
    for (int i = 0; i < kSteps; ++i)
        depth += static_cast<double>(density(q + (enter + (static_cast<float>(i) + 0.5f) * step) * d));
    return glm::exp(-extinction *
                    static_cast<float>(depth * static_cast<double>(step) * static_cast<double>(h)));
}
}  // namespace

std::vector<glm::vec4> TransportStage::read_floor_irradiance() const {
    std::vector<glm::vec4> map = read_floor_map();
    const shaders::TransportParams& p = light_params_.front();
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
                    direct += glm::vec3(light.power) * std::max(0.0f, -light.direction.y) *
                              medium_transmittance(p, x, -glm::vec3(light.direction), 1e30f);
                    continue;
                }
                const glm::vec3 l = glm::vec3(light.position) - x;
                const float r2 = glm::dot(l, l);
                const glm::vec3 to_light = l / std::sqrt(r2);
                const bool in_cone = light.type.x != LIGHT_SPOT ||
                                     glm::dot(-to_light, glm::vec3(light.direction)) >= light.position.w;
                if (in_cone)
                    direct += glm::vec3(light.power) * std::max(0.0f, to_light.y) / r2 *
                              medium_transmittance(p, x, to_light, std::sqrt(r2));
            }
            direct += glm::vec3(p.environment_light);
            glm::vec4& texel_value = map[size_t{j} * floor_texels_ + i];
            texel_value = glm::vec4(glm::max(glm::vec3(texel_value) + direct, glm::vec3(0.0f)), 0.0f);
        }
    return map;
}

std::vector<shaders::PhotonExit> TransportStage::read_photon_exits() const {
    std::vector<shaders::PhotonExit> out(exit_capacity_);
    accum_->exits.read(out.data(), out.size() * sizeof(shaders::PhotonExit));
    return out;
}

}  // namespace refract::scene
