// What the transport passes size and sequence alike, from the lattice alone: the floor map's and light
// map's texels, photon shares and exits, eye-ray sample offsets, dispersion.
// The frame's parameters themselves are made from the scene document on the render side
// (render/transport_inputs.h).
#pragma once

#include <array>
#include <vector>

#include "passes/grid_geometry.h"
#include "transport.h"

namespace refract::passes {

// The sub-pixel offset of eye-ray sample `index` (0: the pixel centre; then a Halton (2, 3) sequence
// over the pixel's square, so any number of samples covers it evenly).
glm::vec2 view_sample_offset(uint32_t index);

// Photons per light out of `photons`, in proportion to the flux each sends through its emitter
// (`powers`, W): one at least for a light that sends any, none for one that sends none; all for the
// first when none sends any. A share rounds, so the total may differ from `photons` by under one per light.
std::vector<uint32_t> photon_shares(uint32_t photons, const std::vector<double>& powers);

// Photon exits a frame records (RunOptions::record_photon_exits) for `photons` emission samples: one per
// sample and channel under dispersive transport, else one per sample.
uint32_t photon_exit_count(uint32_t photons, uint32_t channels);

// Each channel's index contrast against the medium relative to the field's (TransportParams::dispersion)
// for Abbe number `abbe` (0: none, all 1).
glm::vec3 dispersion_scales(double abbe);

// Texels per side of the floor caustic map for this grid.
uint32_t floor_map_texels(const passes::GridGeometry& grid);

// Texels per side of the light map (DirectLightPass) for this grid and photon count, and the most any
// photon count uses (what a scene allocates).
uint32_t light_map_texels(const passes::GridGeometry& grid, uint32_t photons);
uint32_t light_map_capacity(const passes::GridGeometry& grid);

}  // namespace refract::passes
