// The colour and brightness of a blackbody at a temperature, for volumes that emit from a temperature
// grid (protocol::VolumeEmission::temperature_grid): Planck's law integrated against the CIE 1931
// colour-matching functions, in linear sRGB.
#pragma once

#include <glm/glm.hpp>

namespace refract::scene {

// The temperature whose blackbody has luminance 1 in blackbody_rgb.
inline constexpr double kBlackbodyReferenceKelvin = 1500.0;

// A blackbody's spectral radiance at `kelvin` in linear sRGB (D65 white), relative to the luminance of
// one at kBlackbodyReferenceKelvin, out-of-gamut channels clamped to 0: so 1500 K has luminance 1 and a
// hotter body more, as Planck's law says (about 40x at 2000 K). 0 at or below 0 K, and above 40,000 K
// the value at 40,000 K.
glm::dvec3 blackbody_rgb(double kelvin);

// The CIE 1931 xyY of the same blackbody (Y relative as above), the linear-sRGB step left out: what
// tests compare with published chromaticities of the Planckian locus.
glm::dvec3 blackbody_xyY(double kelvin);

}  // namespace refract::scene
