#pragma once
// Where an imported set's lights are, from the mirror spheres in its frames (RTI sets put one or
// two in every image for this). Each image's highlight on each sphere, reflected at the sphere
// (capture/light_calibration.h), gives a ray toward that image's LED:
//  * one sphere: each light's direction (the mean reflected ray), no positions;
//  * two or more: positions where the rays cross. When the crossed positions lie on a sphere (a
//    dome: RMS distance to the fitted sphere within kDomeTolerance of its radius), every light is
//    put where its rays meet that sphere, which also places the lights whose rays cross too
//    shallowly to triangulate (those along the line through the spheres).
// Geometry: a camera looking straight down -Z at the plane z = 0 that the object and the spheres
// rest on, the image centre's ray through the stage origin, +Y up the image:
//  * orthographic (no focal length): sphere centres at z = their radius; metres from the spheres'
//    radius when it is given, otherwise a nominal 0.1 mm per source pixel (directions and the
//    field's relative falloff do not depend on the scale);
//  * pinhole (focal_length_px, and the spheres' radius): each sphere placed in depth by its
//    outline's size, the table where they rest, the camera that far above it. A view tilts a
//    sphere's view ray by its angle off the axis, and its reflected ray by as much: an
//    orthographic reading of a pinhole photograph errs by about the half field of view at the
//    frame's edge.
#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/light_calibration.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"

namespace ls::capture {

inline constexpr double kNominalMetresPerPixel = 1e-4;
inline constexpr double kDomeTolerance = 0.02;

struct SphereLightOptions {
  std::vector<SphereOutline> outlines;  // In the images' pixels; empty: no placement.
  double radius_m = 0.0;                // The spheres' radius; 0: unknown (nominal scale).
  double focal_length_px = 0.0;         // > 0: a pinhole camera (needs radius_m); 0: orthographic.
  HighlightOptions highlight;
  // Empty when valid; otherwise a sentence naming the option.
  std::string validate(int image_width, int image_height) const;
};

// A dome fitted to positions (fit_sphere).
struct FittedDome {
  Eigen::Vector3d centre{0, 0, 0};
  double radius_m = 0.0;
  double rms_m = 0.0;  // Of the triangulated positions about it.
};

struct PlacedLights {
  FieldView view;  // The images' view, metres (the plane z = 0 is the table's).
  std::vector<std::optional<Eigen::Vector3d>> positions;   // Per light (two or more spheres).
  std::vector<std::optional<Eigen::Vector3d>> directions;  // Per light, unit; unset: not found.
  std::vector<ImageProblem> problems;                      // led_index: the light; image: its name.
  // How the lights were placed, a sentence for the import's summary.
  std::string description;
};

// Rows [y0, y1) of light `light`'s image as linear RGB (width x (y1 - y0)).
using ImageRows = std::function<Image(int light, int y0, int y1)>;

// Reads the rows the spheres cover from each of `names.size()` images of width x height (in
// parallel) and places their lights. Progress: phase "spheres".
PlacedLights place_lights_from_spheres(int width, int height, const std::vector<std::string>& names,
                                       const ImageRows& read, const SphereLightOptions& options,
                                       const ProgressFn& progress = {});

// The sphere through 4 or more points (least squares on |p|^2 + b.p + c = 0), or nullopt when they
// are degenerate (coplanar, too few).
std::optional<FittedDome> fit_sphere(const std::vector<Eigen::Vector3d>& points);

}  // namespace ls::capture
