#version 460
#extension GL_GOOGLE_include_directive : require
// The refractive index field: n and grad n per voxel in one texel, so one trilinear fetch serves a ray
// step. Gradients are per voxel length (the tracers step in voxel units). Uniform objects map coverage
// to n between the medium's and the object's index; Luneburg and Maxwell lenses are the analytic test
// beds, evaluated exactly at voxel centres; imported grids come from a simulation.
//
// In a scene of several objects, an edit recomposes only the region it changed (the boxes of the objects
// it moved, before and after): a dispatch sets the region to the medium (a uniform object of no coverage),
// then each object whose box meets it writes its part, joining what the objects before it left: a voxel takes the field of the object with the most coverage there, and where
// coverages are equal (inside both) of the one of higher index, whatever the order. So where one object
// only grazes another's box (the smoothing's tails) it leaves it be, and where two overlap the one more
// inside wins, the denser one inside both.
#include "volume_build.h"

layout(local_size_x = VOLUME_GROUP_3D, local_size_y = VOLUME_GROUP_3D, local_size_z = VOLUME_GROUP_3D) in;
layout(std430, binding = INDEX_BINDING_COVERAGE) readonly buffer Coverage { float coverage[]; };
layout(std430, binding = INDEX_BINDING_GRID) readonly buffer Grid { float grid[]; };
layout(binding = INDEX_BINDING_INDEX_FIELD, rgba32f) uniform image3D index_field;
layout(binding = INDEX_BINDING_COVERAGE_IMAGE, rg32f) uniform image3D coverage_image;
layout(push_constant) uniform Push { IndexFieldPush push; };

float coverage_at(ivec3 v) {
    ivec3 c = clamp(v, ivec3(0), ivec3(push.dims.xyz) - 1);
    return coverage[(uint(c.z) * push.dims.y + uint(c.y)) * push.dims.x + uint(c.x)];
}

float grid_at(ivec3 v) {
    ivec3 c = clamp(v, ivec3(0), ivec3(push.dims.xyz) - 1);
    return grid[(uint(c.z) * push.dims.y + uint(c.y)) * push.dims.x + uint(c.x)];
}

// grad n per voxel length from the 3 x 3 x 3 values around a voxel (`around[(z * 3 + y) * 3 + x]`, the
// border clamped): each axis's central difference, averaged across its two other axes with weights
// 1 4 1 / 6. A plain central difference errs by h^2/6 times the third derivative along its own axis,
// which tilts the normal of a shell the lattice does not line up with, and a caustic focused through
// that shell shows the lattice as rings (docs/rendering.md, "Ring moire in caustics"). Averaged this way the error
// is h^2/6 grad(laplacian n) on every axis, along the normal of a locally spherical shell; the weights
// stay positive (no ringing in the shell's tails) and a flat interface's integral stays exact.
vec3 isotropic_gradient(float around[27]) {
    const float across[3] = float[3](1.0, 4.0, 1.0);
    vec3 g = vec3(0.0);
    for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
            float w = across[a] * across[b];
            g.x += w * (around[(a * 3 + b) * 3 + 2] - around[(a * 3 + b) * 3]);
            g.y += w * (around[(a * 3 + 2) * 3 + b] - around[a * 9 + b]);
            g.z += w * (around[(2 * 3 + a) * 3 + b] - around[a * 3 + b]);
        }
    }
    return g / 72.0;
}

// The field the gradient is taken of: an imported grid's values, else the coverage.
float differentiated_at(ivec3 v) { return kMode == INDEX_KIND_GRID ? grid_at(v) : coverage_at(v); }

vec3 gradient_at(ivec3 v) {
    float around[27];
    for (int i = 0; i < 27; ++i) around[i] = differentiated_at(v + ivec3(i % 3, (i / 3) % 3, i / 9) - 1);
    return isotropic_gradient(around);
}

void main() {
    uvec3 id = gl_GlobalInvocationID;
    if (any(greaterThanEqual(id, push.extent.xyz))) return;
    ivec3 v = ivec3(id + push.first.xyz);
    float h = push.origin.w;
    float c = coverage_at(v);
    vec4 texel;
    uint kind = kMode;  // INDEX_KIND_*
    if (kind == INDEX_KIND_UNIFORM) {
        texel = vec4(push.n_medium + (push.n_object - push.n_medium) * c,
                     (push.n_object - push.n_medium) * gradient_at(v));
    } else if (kind == INDEX_KIND_GRID) {
        texel = vec4(grid_at(v), gradient_at(v));
    } else {
        vec3 x = push.origin.xyz + (vec3(v) + 0.5) * h;
        vec3 d = x - push.sphere.xyz;
        float radius = push.sphere.w;
        float q = dot(d, d) / (radius * radius);  // (r / R)^2
        if (q >= 1.0) {
            texel = vec4(push.n_medium, 0.0, 0.0, 0.0);
        } else if (kind == INDEX_KIND_LUNEBURG) {
            float n = sqrt(2.0 - q);
            texel = vec4(n, -d / (radius * radius * n) * h);
        } else {
            float s = 1.0 + q;
            texel = vec4(push.n_object / s, -2.0 * push.n_object * d / (radius * radius * s * s) * h);
        }
    }
    ivec3 at = v + ivec3(push.offset.xyz);
    uint object = push.offset.w;
    if (object > 0u) {
        vec2 held = imageLoad(coverage_image, at).rg;
        if (held.g > 0.0 && (c < held.r || (c == held.r && texel.x <= imageLoad(index_field, at).x))) return;
    }
    imageStore(index_field, at, texel);
    imageStore(coverage_image, at, vec4(c, float(object), 0.0, 0.0));
}
