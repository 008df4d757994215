// How the viewing pass and view_refine.comp walk an image: in 8x8 tiles, and within a tile in Morton
// order, so the pixels of a subgroup (8 on lavapipe) form a 4x2 block rather than a row: their rays
// stay closer together, cross octree leaves at more similar distances, and lanes idle less.
#if VIEW_GROUP_SIZE != 8
#error "the Morton order below is written for 8x8 tiles"
#endif

uint even_bits(uint v) { return (v & 1u) | ((v >> 1u) & 2u) | ((v >> 2u) & 4u); }

// Pixel `within` (0..63) of `tile` (column, row of 8x8 tiles).
uvec2 tile_pixel(uvec2 tile, uint within) {
    return tile * VIEW_GROUP_SIZE + uvec2(even_bits(within), even_bits(within >> 1u));
}
