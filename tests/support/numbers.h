// Constants the tests share. Test files of one executable may be compiled as one unit (the
// presets' unity build), so a constant two files need is defined here once.
#pragma once

#include <limits>
#include <numbers>

namespace afr::testing {

inline constexpr float kInf = std::numeric_limits<float>::infinity();
inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
inline constexpr double kDeg = std::numbers::pi / 180.0;  // one degree in radians

}  // namespace afr::testing
