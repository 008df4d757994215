// Trilinear interpolation of a 3D storage image read texel by texel: what a linear, clamp-to-edge
// sampler returns at level 0 for normalized coordinates, up to rounding (lavapipe's sampler fuses each
// interpolation's multiply and add; a shader's are rounded apart). lavapipe runs a filtered fetch of a float
// format as an out-of-line function, around which the calling loop's live registers go to the stack; an
// image load is inlined. So the transport reads every grid this way: a still's view 0.88-0.93x, the smoke
// past glass's camera edit 0.77-0.79x (docs/perf-log/2026-12-07-grids-read-texel-by-texel.md). GLSL passes
// no image to a function: TRILINEAR_CORNERS lists a cell's eight loads.

// The texels around normalized point q of an image of `size` texels, and q's weights between them.
struct TrilinearCell {
    ivec3 lo;
    ivec3 hi;
    vec3 w;
};

TrilinearCell trilinear_cell(vec3 q, ivec3 size) {
    vec3 n = vec3(size);
    vec3 u = max(min(q * n, n) - 0.5, vec3(0.0));
    vec3 low = floor(u);
    ivec3 lo = ivec3(low);
    return TrilinearCell(lo, min(lo + 1, size - 1), u - low);
}

// A cell's eight texels, x fastest, then y, then z: trilinear_blend's arguments.
#define TRILINEAR_CORNERS(image, c)                                                                       \
    imageLoad(image, c.lo), imageLoad(image, ivec3(c.hi.x, c.lo.y, c.lo.z)),                              \
        imageLoad(image, ivec3(c.lo.x, c.hi.y, c.lo.z)), imageLoad(image, ivec3(c.hi.x, c.hi.y, c.lo.z)), \
        imageLoad(image, ivec3(c.lo.x, c.lo.y, c.hi.z)), imageLoad(image, ivec3(c.hi.x, c.lo.y, c.hi.z)), \
        imageLoad(image, ivec3(c.lo.x, c.hi.y, c.hi.z)), imageLoad(image, c.hi)

// Along x, then y, then z, as the sampler interpolates.
vec4 trilinear_blend(TrilinearCell c, vec4 v000, vec4 v100, vec4 v010, vec4 v110,
                     vec4 v001, vec4 v101, vec4 v011, vec4 v111) {
    vec4 y0 = mix(mix(v000, v100, c.w.x), mix(v010, v110, c.w.x), c.w.y);
    vec4 y1 = mix(mix(v001, v101, c.w.x), mix(v011, v111, c.w.x), c.w.y);
    return mix(y0, y1, c.w.z);
}

// The interpolated value of `image` at the point of `cell`.
#define TRILINEAR_AT(image, cell) trilinear_blend(cell, TRILINEAR_CORNERS(image, cell))
