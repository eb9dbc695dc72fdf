// The sRGB transfer functions as IEC 61966-2-1 writes them, in double precision: the reference
// the tests hold afr's own conversions (and the glTF loader's) against.
#pragma once

#include <cmath>

namespace afr::testing {

inline double reference_srgb_to_linear(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

inline double reference_linear_to_srgb(double c) {
  return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}

}  // namespace afr::testing
