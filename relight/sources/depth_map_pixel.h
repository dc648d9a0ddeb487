#pragma once
// Internal to relight_sources: where a ray through the scene's depth map (shadow_geometry.h) falls,
// for its carving and its shadow rays alike.

namespace ls::relight {

// The pixel a ray's coordinate falls in: round half up where it is >= -0.5 (std::lround, a call
// into libm, was a third of the marching), negative below: outside the map either way.
inline int pixel_of(float coordinate) { return int(coordinate + 1.5f) - 1; }

}  // namespace ls::relight
