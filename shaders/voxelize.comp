#version 460
#extension GL_GOOGLE_include_directive : require
// Voxelization: the occupancy of a triangle mesh, filtered by a separable kernel and sampled at voxel centres.
// CAST: one thread per voxel column along `axis` (its intervals and counts bound for that axis); S x S rays
// per column find every surface crossing and turn them into inside intervals by the nonzero winding rule
// (robust to inconsistent parity and to meshes wound inside out, as some OBJ exporters write them). A
// column whose crossings do not balance (a hole in the mesh) or overflow marks its rays unreliable (count
// -1) so the other two axes decide there.
// GATHER_*: one thread per voxel column, into that axis's coverage (bound as x: lavapipe 22.3 runs every side
// of a branch, so one binding beats choosing among three). Along the axis the filter is exact, the
// kernel's integral over each inside interval; across it each ray stands for the 1/S x 1/S of the plane
// around it, weighted by the kernel at its own position. BOX: the kernel is the voxel, so the value is
// its covered fraction. SPLINE: the quadratic B-spline (three voxels wide, variance 1/4 voxel^2): the
// surface is filtered before it is sampled, and the spline's spectrum is the box's cubed, so little is
// left for the lattice to alias into the grid (the box's sidelobes fold back as rings in a sphere's
// caustic; docs/rendering.md, "Ring moire in caustics"). Both kernels
// sum to 1 over the lattice at any offset, so every axis keeps the volume its rays measure.
// COMBINE: per voxel, the mean of the reliable axes' values; a mean, not a median, keeps that volume.
#include "volume_build.h"
// The workgroup size comes before linear_id.glsl: gl_WorkGroupSize used ahead of the declaration folds
// to 1, which breaks every dispatch folded past 65535 groups.
layout(local_size_x = VOLUME_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(std430, binding = VOXELIZE_BINDING_TRIANGLES) readonly buffer Triangles { vec4 vertices[]; };
layout(std430, binding = VOXELIZE_BINDING_TILE_RANGES) readonly buffer TileRanges { uvec2 tile_ranges[]; };
layout(std430, binding = VOXELIZE_BINDING_TILE_ITEMS) readonly buffer TileItems { uint tile_items[]; };
layout(std430, binding = VOXELIZE_BINDING_COVERAGE_X) buffer CoverageX { float coverage_x[]; };
layout(std430, binding = VOXELIZE_BINDING_COVERAGE_Y) buffer CoverageY { float coverage_y[]; };
layout(std430, binding = VOXELIZE_BINDING_COVERAGE_Z) buffer CoverageZ { float coverage_z[]; };
layout(std430, binding = VOXELIZE_BINDING_COVERAGE) writeonly buffer Coverage { float coverage[]; };
layout(std430, binding = VOXELIZE_BINDING_INTERVALS) buffer Intervals { vec2 intervals[]; };
layout(std430, binding = VOXELIZE_BINDING_INTERVAL_COUNTS) buffer IntervalCounts { int interval_counts[]; };
layout(std430, binding = VOXELIZE_BINDING_STEPS) buffer Steps { float steps[]; };
layout(push_constant) uniform Push { VoxelizePush push; };

uint voxel_index(uvec3 v) { return (v.z * push.dims.y + v.y) * push.dims.x + v.x; }

layout(constant_id = VOXELIZE_CONSTANT_SUBSAMPLES) const uint kSubsamples = VOXELIZE_SUBSAMPLES;
const uint kRays = kSubsamples * kSubsamples;

// Where ray r of a column crosses its plane, from the column's corner (voxels). The small irrational
// offsets keep rays off edges and vertices.
vec2 ray_offset(uint r) {
    return vec2((float(r % kSubsamples) + 0.5) / float(kSubsamples) + 1.3217e-4,
                (float(r / kSubsamples) + 0.5) / float(kSubsamples) + 0.7731e-4);
}

void cast_rays() {
    uint axis = push.axis;
    uint ua = (axis + 1u) % 3u;
    uint va = (axis + 2u) % 3u;
    uvec3 dims = push.dims.xyz;
    uint column = linear_invocation();
    uint count_u = dims[ua];
    if (column >= count_u * dims[va]) return;
    uint iu = column % count_u;
    uint iv = column / count_u;
    uint tile = (iv / push.tile_size) * push.tiles_u + iu / push.tile_size;
    uvec2 range = tile_ranges[tile];
    // No triangle over the column (most columns): its rays cross nothing, and their counts are the fill's
    // zeros already.
    if (range.y == 0u) return;

    // Each triangle of the column's bin is loaded once and tested against all of its rays (storage-buffer
    // loads run lane by lane on lavapipe; loading per ray cost a third of the pass). Ray r keeps its
    // crossings in slots [r * VOXELIZE_MAX_CROSSINGS, (r + 1) * VOXELIZE_MAX_CROSSINGS).
    float crossing_w[kRays * VOXELIZE_MAX_CROSSINGS];
    int crossing_wind[kRays * VOXELIZE_MAX_CROSSINGS];
    int count[kRays];
    for (uint r = 0u; r < kRays; ++r) count[r] = 0;
    bool reliable = true;
    for (uint t = 0u; t < range.y; ++t) {
        uint tri = tile_items[range.x + t];
        vec3 a = vertices[3u * tri].xyz, b = vertices[3u * tri + 1u].xyz, c = vertices[3u * tri + 2u].xyz;
        vec2 pa = vec2(a[ua], a[va]), pb = vec2(b[ua], b[va]), pc = vec2(c[ua], c[va]);
        float area = (pb.x - pa.x) * (pc.y - pa.y) - (pb.y - pa.y) * (pc.x - pa.x);
        if (area == 0.0) continue;  // parallel to the rays
        for (uint r = 0u; r < kRays; ++r) {
            vec2 p = vec2(iu, iv) + ray_offset(r);
            float w0 = (pb.x - p.x) * (pc.y - p.y) - (pb.y - p.y) * (pc.x - p.x);
            float w1 = (pc.x - p.x) * (pa.y - p.y) - (pc.y - p.y) * (pa.x - p.x);
            float w2 = area - w0 - w1;
            bool inside = area > 0.0 ? (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0)
                                     : (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
            if (!inside) continue;
            if (count[r] == VOXELIZE_MAX_CROSSINGS) { reliable = false; continue; }
            uint slot = r * VOXELIZE_MAX_CROSSINGS + uint(count[r]);
            crossing_w[slot] = (w0 * a[axis] + w1 * b[axis] + w2 * c[axis]) / area;
            // area > 0 means the normal has a positive component along the ray: the ray leaves there.
            crossing_wind[slot] = area > 0.0 ? -1 : 1;
            ++count[r];
        }
    }
    for (uint r = 0u; r < kRays && reliable; ++r) {
        int first = int(r * VOXELIZE_MAX_CROSSINGS), n = count[r];
        // Insertion sort by depth: crossings per ray are few.
        for (int i = first + 1; i < first + n; ++i) {
            float w = crossing_w[i];
            int k = crossing_wind[i];
            int j = i - 1;
            while (j >= first && crossing_w[j] > w) {
                crossing_w[j + 1] = crossing_w[j];
                crossing_wind[j + 1] = crossing_wind[j];
                --j;
            }
            crossing_w[j + 1] = w;
            crossing_wind[j + 1] = k;
        }
        int winding = 0;
        for (int i = first; i < first + n; ++i) winding += crossing_wind[i];
        if (winding != 0) { reliable = false; break; }
        // The inside intervals, unclamped: an object that volume.bounds cuts continues past the grid.
        uint ray = column * kRays + r;
        int intervals_found = 0;
        for (int i = first; i < first + n; ++i) {
            winding += crossing_wind[i];
            // Nonzero rule: an inside-out mesh winds -1 inside and must fill the same.
            if (winding == 0 || i + 1 >= first + n || crossing_w[i + 1] <= crossing_w[i]) continue;
            if (intervals_found == VOXELIZE_MAX_INTERVALS) { reliable = false; break; }
            intervals[ray * VOXELIZE_MAX_INTERVALS + uint(intervals_found)] = vec2(crossing_w[i], crossing_w[i + 1]);
            ++intervals_found;
        }
        interval_counts[ray] = intervals_found;
    }
    if (!reliable) {
        for (uint r = 0u; r < kRays; ++r) interval_counts[column * kRays + r] = -1;
    }
}

// The kernel at t voxels from its centre, and its integral up to t.
float kernel(float t) {
    float a = abs(t);
    if (kMode == VOXELIZE_MODE_GATHER_BOX) return a < 0.5 ? 1.0 : 0.0;
    return a < 0.5 ? 0.75 - a * a : (a < 1.5 ? 0.5 * (1.5 - a) * (1.5 - a) : 0.0);
}
float kernel_integral(float t) {
    if (kMode == VOXELIZE_MODE_GATHER_BOX) return clamp(t + 0.5, 0.0, 1.0);
    float a = abs(t);
    float beyond = a < 0.5 ? 0.5 - 0.75 * a + a * a * a / 3.0 : (a < 1.5 ? (1.5 - a) * (1.5 - a) * (1.5 - a) / 6.0 : 0.0);
    return t < 0.0 ? beyond : 1.0 - beyond;
}
const float kReach = kMode == VOXELIZE_MODE_GATHER_BOX ? 0.5 : 1.5;  // the kernel's half width
const int kNeighbours = kMode == VOXELIZE_MODE_GATHER_BOX ? 0 : 1;     // columns it reaches each side

uint voxel_along(uvec3 dims, uint axis, uint iu, uint iv, uint k) {
    uvec3 voxel;
    voxel[axis] = k;
    voxel[(axis + 1u) % 3u] = iu;
    voxel[(axis + 2u) % 3u] = iv;
    return voxel_index(voxel);
}

void gather() {
    uint axis = push.axis;
    uvec3 dims = push.dims.xyz;
    uint column = linear_invocation();
    uint count_u = dims[(axis + 1u) % 3u], count_v = dims[(axis + 2u) % 3u];
    if (column >= count_u * count_v) return;
    uint iu = column % count_u;
    uint iv = column / count_u;
    int length_along = int(dims[axis]);
    bool reliable = true;
    bool crossed = false;  // some ray within the kernel's reach crosses the surface
    // Each crossing adds (entering) or takes away (leaving) the kernel's integral up to each voxel centre:
    // the centres within its reach get that here, those past it the whole weight, through `steps`, whose
    // running sum along the column is added at the end.
    for (int du = -kNeighbours; du <= kNeighbours; ++du) {
        for (int dv = -kNeighbours; dv <= kNeighbours; ++dv) {
            // Past the grid's side a column's rays stand in for the next one, as the object continues there.
            uint source = uint(clamp(int(iv) + dv, 0, int(count_v) - 1)) * count_u + uint(clamp(int(iu) + du, 0, int(count_u) - 1));
            for (uint r = 0u; r < kRays; ++r) {
                int n = interval_counts[source * kRays + r];
                if (n < 0) reliable = false;
                vec2 from_centre = vec2(du, dv) + ray_offset(r) - 0.5;
                float weight = kernel(from_centre.x) * kernel(from_centre.y) / float(kRays);
                if (weight == 0.0) continue;
                crossed = crossed || n > 0;
                for (int i = 0; i < n; ++i) {
                    vec2 interval = intervals[(source * kRays + r) * VOXELIZE_MAX_INTERVALS + uint(i)];
                    for (int side = 0; side < 2; ++side) {
                        float w = interval[side];
                        float signed_weight = side == 0 ? weight : -weight;
                        int k_last = int(floor(w + kReach - 0.5));  // the last centre within reach
                        for (int k = max(int(ceil(w - kReach - 0.5)), 0); k <= min(k_last, length_along - 1); ++k) {
                            uint index = voxel_along(dims, axis, iu, iv, uint(k));
                            coverage_x[index] += signed_weight * kernel_integral(float(k) + 0.5 - w);
                        }
                        if (k_last + 1 < length_along)
                            steps[voxel_along(dims, axis, iu, iv, uint(max(k_last + 1, 0)))] += signed_weight;
                    }
                }
            }
        }
    }
    // Nothing added: the column's coverage and steps are still the zeros they were filled with. Most
    // columns lie so (outside the object's shadow on this axis's plane), and the running sum below is
    // four storage accesses per voxel, lane by lane on lavapipe.
    if (!crossed && reliable) return;
    float past = 0.0;
    for (uint k = 0u; k < uint(length_along); ++k) {
        uint index = voxel_along(dims, axis, iu, iv, k);
        past += steps[index];
        steps[index] = 0.0;  // clear for the next axis
        coverage_x[index] = reliable ? coverage_x[index] + past : -1.0;
    }
}

void combine() {
    uint i = linear_invocation();
    if (i >= push.dims.x * push.dims.y * push.dims.z) return;
    float values[3] = float[3](coverage_x[i], coverage_y[i], coverage_z[i]);
    float sum = 0.0;
    int valid = 0;
    for (int a = 0; a < 3; ++a) {
        if (values[a] < -0.5) continue;  // -1: unreliable
        sum += values[a];
        ++valid;
    }
    float result = valid > 0 ? sum / float(valid) : 0.0;
    // A full voxel sums a hundred or more kernel weights whose exact sum is 1 (float rounding misses it
    // by up to ~1e-5), an empty one the weights a ray's crossings add and take away again (ulps of a
    // weight, ~1e-8 and less); full and empty voxels must be exactly that (no gradient inside or outside
    // the object). The spline's own values that close to 1 or 0 lie within 0.04 voxel of its reach.
    coverage[i] = result > 1.0 - 1e-5 ? 1.0 : (result < 1e-7 ? 0.0 : result);
}

void main() {
    if (kMode == VOXELIZE_MODE_CAST) cast_rays();
    else if (kMode == VOXELIZE_MODE_COMBINE) combine();
    else gather();
}
