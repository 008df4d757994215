#include "render/blackbody.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace refract::scene {

namespace {

// One lobe of Wyman, Sloan and Shirley's fit to the CIE 1931 2-degree colour-matching functions
// ("Simple Analytic Approximations to the CIE XYZ Color Matching Functions", JCGT 2013): a Gaussian
// with another width on each side of its peak.
double lobe(double nm, double peak, double below, double above) {
    const double t = (nm - peak) / (nm < peak ? below : above);
    return std::exp(-0.5 * t * t);
}

glm::dvec3 matching(double nm) {
    return {1.056 * lobe(nm, 599.8, 37.9, 31.0) + 0.362 * lobe(nm, 442.0, 16.0, 26.7) - 0.065 * lobe(nm, 501.1, 20.4, 26.2),
            0.821 * lobe(nm, 568.8, 46.9, 40.5) + 0.286 * lobe(nm, 530.9, 16.3, 31.1),
            1.217 * lobe(nm, 437.0, 11.8, 36.0) + 0.681 * lobe(nm, 459.0, 26.0, 13.8)};
}

// Planck's spectral radiance at wavelength `nm`, up to a constant factor.
double planck(double nm, double kelvin) {
    constexpr double kSecondRadiation = 1.438776877e7;  // h c / k_B in nm K
    const double x = kSecondRadiation / (nm * kelvin);
    if (x > 700.0) return 0.0;
    const double um = nm * 1e-3;
    return 1.0 / (um * um * um * um * um * std::expm1(x));
}

// XYZ of the blackbody, 360..830 nm in 1 nm steps, up to the same constant factor.
glm::dvec3 xyz(double kelvin) {
    glm::dvec3 sum(0.0);
    for (int nm = 360; nm <= 830; ++nm) sum += planck(nm, kelvin) * matching(nm);
    return sum;
}

constexpr double kTableStep = 10.0;     // kelvin
constexpr double kTableTop = 40000.0;

// XYZ relative to the reference's luminance, every kTableStep kelvin from 0 to kTableTop: built once,
// as a temperature grid asks for millions of values.
const std::vector<glm::dvec3>& table() {
    static const std::vector<glm::dvec3> values = [] {
        const double reference = xyz(kBlackbodyReferenceKelvin).y;
        std::vector<glm::dvec3> v(static_cast<size_t>(kTableTop / kTableStep) + 1, glm::dvec3(0.0));
        for (size_t i = 1; i < v.size(); ++i) v[i] = xyz(static_cast<double>(i) * kTableStep) / reference;
        return v;
    }();
    return values;
}

glm::dvec3 relative_xyz(double kelvin) {
    if (!(kelvin > 0.0)) return glm::dvec3(0.0);
    const double at = std::min(kelvin, kTableTop) / kTableStep;
    const size_t i = std::min(static_cast<size_t>(at), table().size() - 2);
    const double f = at - static_cast<double>(i);
    return glm::mix(table()[i], table()[i + 1], f);
}

}  // namespace

glm::dvec3 blackbody_rgb(double kelvin) {
    const glm::dvec3 c = relative_xyz(kelvin);
    const glm::dvec3 rgb(3.2404542 * c.x - 1.5371385 * c.y - 0.4985314 * c.z,
                         -0.9692660 * c.x + 1.8760108 * c.y + 0.0415560 * c.z,
                         0.0556434 * c.x - 0.2040259 * c.y + 1.0572252 * c.z);
    return glm::max(rgb, glm::dvec3(0.0));
}

glm::dvec3 blackbody_xyY(double kelvin) {
    const glm::dvec3 c = relative_xyz(kelvin);
    const double sum = c.x + c.y + c.z;
    if (!(sum > 0.0)) return glm::dvec3(0.0);
    return {c.x / sum, c.y / sum, c.y};
}

}  // namespace refract::scene
