#version 460
#extension GL_GOOGLE_include_directive : require
// Voxelization: fractional coverage of a triangle mesh on the grid.
// COLUMNS: one thread per voxel column along `axis`, into that axis's coverage (bound as x: lavapipe
// runs every side of a branch, so one binding beats choosing among three); S x S rays per column find every surface crossing,
// turn them into inside intervals by the nonzero winding rule (robust to inconsistent parity and to
// meshes wound inside out, as some OBJ exporters write them), and add the exact inside length per
// voxel. A column whose crossings do not balance (a hole in the mesh) or overflow is marked unreliable
// (-1) so the other two axes decide there.
// COMBINE: per voxel, the median of the reliable axes' coverage (a majority vote that keeps fractions).
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
layout(push_constant) uniform Push { VoxelizePush push; };

uint voxel_index(uvec3 v) { return (v.z * push.dims.y + v.y) * push.dims.x + v.x; }

void columns() {
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
    uint length_along = dims[axis];
    const uint rays = VOXELIZE_SUBSAMPLES * VOXELIZE_SUBSAMPLES;
    float weight = 1.0 / float(rays);

    // Each triangle of the column's bin is loaded once and tested against all of its rays (storage-buffer
    // loads run lane by lane on lavapipe; loading per ray cost a third of the pass). Ray r keeps its
    // crossings in slots [r * VOXELIZE_MAX_CROSSINGS, (r + 1) * VOXELIZE_MAX_CROSSINGS).
    float crossing_w[rays * VOXELIZE_MAX_CROSSINGS];
    int crossing_wind[rays * VOXELIZE_MAX_CROSSINGS];
    int count[rays];
    for (uint r = 0u; r < rays; ++r) count[r] = 0;
    bool reliable = true;
    for (uint t = 0u; t < range.y; ++t) {
        uint tri = tile_items[range.x + t];
        vec3 a = vertices[3u * tri].xyz, b = vertices[3u * tri + 1u].xyz, c = vertices[3u * tri + 2u].xyz;
        vec2 pa = vec2(a[ua], a[va]), pb = vec2(b[ua], b[va]), pc = vec2(c[ua], c[va]);
        float area = (pb.x - pa.x) * (pc.y - pa.y) - (pb.y - pa.y) * (pc.x - pa.x);
        if (area == 0.0) continue;  // parallel to the rays
        for (uint r = 0u; r < rays; ++r) {
            // Sub-sample positions are offset by small irrational amounts so rays miss edges and vertices.
            vec2 p = vec2(float(iu) + (float(r % VOXELIZE_SUBSAMPLES) + 0.5) / float(VOXELIZE_SUBSAMPLES) + 1.3217e-4,
                          float(iv) + (float(r / VOXELIZE_SUBSAMPLES) + 0.5) / float(VOXELIZE_SUBSAMPLES) + 0.7731e-4);
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
    for (uint r = 0u; r < rays && reliable; ++r) {
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
        // Walk the sorted crossings and add each inside interval's overlap with every voxel.
        for (int i = first; i < first + n; ++i) {
            winding += crossing_wind[i];
            // Nonzero rule: an inside-out mesh winds -1 inside and must fill the same.
            if (winding == 0 || i + 1 >= first + n) continue;
            float w_in = clamp(crossing_w[i], 0.0, float(length_along));
            float w_out = clamp(crossing_w[i + 1], 0.0, float(length_along));
            if (w_out <= w_in) continue;
            uint k_first = uint(floor(w_in));
            uint k_last = min(uint(ceil(w_out)), length_along);
            for (uint k = k_first; k < k_last; ++k) {
                float overlap = min(w_out, float(k + 1u)) - max(w_in, float(k));
                if (overlap <= 0.0) continue;
                uvec3 voxel;
                voxel[axis] = k;
                voxel[ua] = iu;
                voxel[va] = iv;
                uint index = voxel_index(voxel);
                coverage_x[index] += overlap * weight;
            }
        }
    }
    if (!reliable) {
        for (uint k = 0u; k < length_along; ++k) {
            uvec3 voxel;
            voxel[axis] = k;
            voxel[ua] = iu;
            voxel[va] = iv;
            coverage_x[voxel_index(voxel)] = -1.0;
        }
    }
}

void combine() {
    uint i = linear_invocation();
    if (i >= push.dims.x * push.dims.y * push.dims.z) return;
    float values[3] = float[3](coverage_x[i], coverage_y[i], coverage_z[i]);
    float sum = 0.0;
    int valid = 0;
    float lo = 2.0, hi = -1.0;
    for (int a = 0; a < 3; ++a) {
        if (values[a] < 0.0) continue;
        sum += values[a];
        lo = min(lo, values[a]);
        hi = max(hi, values[a]);
        ++valid;
    }
    float result = 0.0;
    if (valid == 3) result = sum - lo - hi;  // the median
    else if (valid > 0) result = sum / float(valid);
    coverage[i] = clamp(result, 0.0, 1.0);
}

void main() {
    if (kMode == VOXELIZE_MODE_COLUMNS) columns();
    else combine();
}
