#pragma once
// Angle conversions: the code computes in radians; users read and write degrees.

#include <numbers>

namespace ls {

inline constexpr double kDegToRad = std::numbers::pi / 180.0;  // Radians per degree.
inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;  // Degrees per radian.

}  // namespace ls
