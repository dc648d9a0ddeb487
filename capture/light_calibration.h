#pragma once
// Light calibration from photographs of calibration targets:
//  * LED directions (and, with two spheres, positions) from mirror-sphere highlights: the sphere's
//    outline is fitted (or given), each image's highlight is located to sub-pixel precision and the
//    camera ray through it is reflected at the sphere.
//  * LED irradiance and colour, and each LED's spatial non-uniformity (flat field), from a matte
//    white plane.
// Every per-image problem is reported (ImageProblem) and that image left out; the rest are used.
//
// Image coordinates: continuous pixels, x right, y down, pixel (i, j) covers [i, i+1) x [j, j+1)
// so its centre is (i + 0.5, j + 0.5) (the simulator's convention). Directions are in the stage
// frame (+Y up, camera on +Z looking toward -Z).
#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/stage.h"

namespace ls::capture {

// The camera that took the calibration photographs: orthographic or pinhole, on +Z looking toward
// -Z, image y toward -Y (CameraSpec's geometry). A chessboard calibration may replace fx, fy, cx,
// cy.
struct ViewCamera {
  int width = 0;
  int height = 0;
  bool orthographic = true;
  double metres_per_pixel = 1.0;             // Orthographic.
  double fx = 0, fy = 0;                     // Pinhole focal lengths, pixels.
  double cx = 0, cy = 0;                     // Principal point, pixels.
  Eigen::Vector3d centre_in_stage{0, 0, 4};  // Pinhole centre.

  static ViewCamera from_spec(const CameraSpec& camera);
  // Orthographic in pixel units (for photographs with no stage geometry, e.g. a cropped probe).
  static ViewCamera orthographic_pixels(int width, int height);

  // The ray through a point of the image: origin and unit direction, stage frame.
  void ray(const Eigen::Vector2d& pixel, Eigen::Vector3d* origin, Eigen::Vector3d* dir) const;
  Eigen::Vector2d project(const Eigen::Vector3d& point_in_stage) const;
};

// A sphere's outline in an image: an ellipse (a circle in orthographic views and on the axis).
struct SphereOutline {
  Eigen::Vector2d center_px{0, 0};
  double radius_px = 0;                      // Mean semi-axis.
  Eigen::Vector2d major_semi_axis_px{0, 0};  // Half the major axis, as a vector.
};

// Finds up to `max_spheres` spheres in a reference image (the spheres brighter than the
// background): Otsu threshold of the luminance, the largest outer contours, holes filled, then
// the area moments of each region (sub-pixel: a half-level threshold makes the area unbiased).
// Regions smaller than min_radius_px are ignored. Sorted left to right.
std::vector<SphereOutline> find_sphere_outlines(const Image& reference, int max_spheres,
                                                double min_radius_px = 8.0);

// For photographs where the sphere is not simply brighter than its background (a chrome sphere
// reflecting a dark room in front of a cluttered one): the strongest circle of the Hough
// transform of the image's edges, radius in [min_radius_px, max_radius_px]. Pixel precision only.
std::optional<SphereOutline> find_sphere_circle_hough(const Image& reference, double min_radius_px,
                                                      double max_radius_px);

// Outlines given as circles, cx, cy, r per sphere (pixels; a trailing incomplete one is ignored).
std::vector<SphereOutline> outlines_from_circles(const std::vector<double>& circles);

struct MirrorSphere {
  Eigen::Vector3d center_in_stage{0, 0, 0};
  double radius_m = 0.0;
};

// Places a sphere seen with `outline`: orthographic views take the centre's x, y and the radius
// from the image (z = center_z_m); pinhole views use the tangent cone through the major axis and
// the sphere's known radius_m to find its distance.
MirrorSphere locate_sphere(const SphereOutline& outline, const ViewCamera& camera, double radius_m,
                           double center_z_m = 0.0);

struct HighlightOptions {
  // Pixels above this fraction of the peak form the blob. Low enough to take in the blurred skirt
  // around a clipped core (less pixel locking: simulated with 4x4 supersampling, 0.05 deg RMS at
  // 0.25 vs 0.13 at 0.5); 8-bit JPEGs whose glare is not symmetric do better with the clipped core
  // alone (0.975).
  double blob_fraction = 0.25;
  // > 0: a clipped highlight (its peak at saturation_level) is located by its core instead, the
  // area above this fraction of the peak, centroid with a sub-pixel edge (the values interpolated
  // between pixel centres): a camera's glare around a clipped highlight is not symmetric, and the
  // core's excesses are all alike, so weighting by them moves its centre a pixel at a time.
  double clipped_core_fraction = 0;
  double min_contrast = 2.0;         // The peak must exceed this times the disc's 90th percentile.
  double min_peak = 1e-6;            // Absolute floor for the peak (image units).
  double min_snr = 30.0;             // ... and its median by this many noise sigmas.
  double second_blob_ratio = 0.2;    // A second blob with this fraction of the first's energy:
                                     // ambiguous (two lights on, an interreflection).
  double max_normal_angle_deg = 72;  // Nearer the rim, the highlight is too foreshortened.
  double saturation_level = 0;       // Values >= this are clipped (0: none); reported.
};

struct Highlight {
  Eigen::Vector2d center_px{0, 0};  // Sub-pixel: centroid weighted by (value - threshold).
  double peak = 0;
  int pixels = 0;
  int saturated_pixels = 0;
};

// The brightest blob inside the sphere's disc, or nullopt with the reason in *problem.
std::optional<Highlight> find_highlight(const Image& image, const SphereOutline& outline,
                                        const HighlightOptions& options, std::string* problem);

// A ray leaving the sphere toward the light: origin on the sphere, unit direction.
struct LightRay {
  Eigen::Vector3d origin{0, 0, 0};
  Eigen::Vector3d dir{0, 0, 1};
  double normal_angle_deg = 0;  // Angle between the sphere normal there and the view ray.
};

// Reflects the camera ray through `pixel` at the sphere: r = 2 (n.v) n - v with v toward the
// camera. nullopt if the ray misses the sphere.
std::optional<LightRay> reflect_at(const ViewCamera& camera, const MirrorSphere& sphere,
                                   const Eigen::Vector2d& pixel);

// The point nearest to all rays (least squares over perpendicular distances) and its RMS distance
// to them; nullopt when the rays are nearly parallel (angles below min_angle_deg: a distant light)
// or the point lies behind a ray origin.
std::optional<Eigen::Vector3d> closest_point_to_rays(const std::vector<LightRay>& rays,
                                                     double* rms_distance_m,
                                                     double min_angle_deg = 0.5);

struct ImageProblem {
  int led_index = -1;
  int sphere = -1;  // -1: the whole image.
  std::string image;
  std::string what;
};

struct LedDirectionEstimate {
  int led_index = 0;
  bool ok = false;
  Eigen::Vector3d dir_in_stage{0, 1, 0};
  std::optional<Eigen::Vector3d> position_in_stage;  // Triangulated (two or more spheres).
  double ray_miss_m = 0;                             // RMS distance of the rays to the position.
  std::vector<LightRay> rays;                        // One per sphere that saw it.
};

struct DirectionCalibration {
  std::vector<LedDirectionEstimate> leds;  // One per image, in order.
  std::vector<ImageProblem> problems;
};

struct DirectionOptions {
  HighlightOptions highlight;
  // A triangulated position further than this from the origin is treated as "at infinity": the
  // direction is the mean reflected direction.
  double max_distance_m = 50.0;
  // Positions are only triangulated from rays that cross at this angle or more (depth error grows
  // as 1/sin of it) and leave their spheres away from the rim (simulated at 1 m with 0.36 m between
  // the spheres: worst error 13 mm without these limits).
  double min_triangulation_angle_deg = 10.0;
  double max_triangulation_normal_deg = 60.0;
};

// One image per LED (images[i] lit by LED i), each showing every sphere. Directions come from the
// triangulated position when there is one (near-field LEDs), otherwise from the mean reflected
// direction.
DirectionCalibration calibrate_directions(const std::vector<const Image*>& images,
                                          const std::vector<std::string>& names,
                                          const std::vector<SphereOutline>& outlines,
                                          const std::vector<MirrorSphere>& spheres,
                                          const ViewCamera& camera,
                                          const DirectionOptions& options);

// ---------------------------------------------------------------------------------------------
// Intensity, colour and flat field from a matte white plane.

struct WhitePlane {
  Eigen::Vector3d center_in_stage{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 1};
  double albedo = 1.0;  // Lambertian reflectance (radiance = albedo / pi * irradiance).
};

// A smooth spatial non-uniformity over the image: s(u, v) = sum of coefficients times the
// monomials 1, u, v, u^2, uv, v^2 with u, v in [-1, 1] across the image (x right, y down).
// s = 1 at the pixel where the stage origin projects.
struct FlatField {
  std::vector<double> coefficients;  // 6 (quadratic); empty means uniform.
  double at(double u, double v) const;
};

struct LedIntensityEstimate {
  int led_index = 0;
  bool ok = false;
  Eigen::Vector3d irradiance_rgb{0, 0, 0};  // At the origin, normal incidence (stage E units).
  FlatField flat_field;
  double fit_rms = 0;  // Relative RMS of the flat-field fit.
};

struct IntensityCalibration {
  std::vector<LedIntensityEstimate> leds;
  std::vector<ImageProblem> problems;
};

struct IntensityOptions {
  double saturation_level = 0;            // Values >= this are clipped; 0: none.
  double max_saturated_fraction = 0.001;  // Of the target's pixels; above: the image is refused.
  double min_signal = 0;                  // Pixels below this are not used (noise floor).
  int step = 2;                           // Pixel stride of the fit.
  // A white plane lit by one LED is smooth: its quadratic shape fits within a few percent (shot
  // noise, a little texture). Above this relative RMS the image is no such plane (noise, the
  // target out of view, another light on): refused, rather than an LED made 3x brighter.
  double max_fit_rms = 0.1;
};

// One image per LED. Each LED's direction (and position, when known) comes from `stage` (already
// direction-calibrated): irradiance on the plane is E * flat * cos(theta) (* (d0/d)^2 for a
// near LED), its radiance albedo / pi times that. The plane must cover the image.
IntensityCalibration calibrate_intensities(const std::vector<const Image*>& images,
                                           const std::vector<std::string>& names,
                                           const Stage& stage, const WhitePlane& plane,
                                           const ViewCamera& camera,
                                           const IntensityOptions& options);

// ---------------------------------------------------------------------------------------------
// Applying the results.

struct StageUpdate {
  int directions_changed = 0;
  int intensities_changed = 0;
};

// Writes the successful estimates into the stage: dir_in_stage (and distance_m when a position was
// triangulated), intensity = mean of irradiance_rgb, color_gain = irradiance_rgb / intensity.
StageUpdate apply_directions(const DirectionCalibration& calibration, Stage* stage);
StageUpdate apply_intensities(const IntensityCalibration& calibration, Stage* stage);

// The flat fields as an image for the stage file's side car: one channel per LED ("led042.Y"),
// width x height samples over the camera's field of view.
Image flat_field_image(const IntensityCalibration& calibration, const Stage& stage, int width,
                       int height);

// The side car read back for the field build: each LED's flat field sampled on a grid over the
// camera's view (as flat_field_image writes it), validated on read.
struct FlatFieldMaps {
  std::filesystem::path file;
  int width = 0, height = 0;
  std::map<int, std::vector<float>> by_led_id;  // width * height samples, row-major, all > 0.

  // The LED's flat field at the centre of pixel (x, y) of an image_width x image_height image of
  // the same view: bilinear between the grid's sample centres, clamped at its border. 1 for an LED
  // the side car does not hold (uniform).
  double at(int led_id, int x, int y, int image_width, int image_height) const;
};

// Reads `file`: every channel must be "ledNNN.Y" naming an LED of the stage, once, and every value
// finite and positive. Otherwise InputError "FILE: channel 'led042.Y': expected ..., got ...".
FlatFieldMaps read_flat_field(const std::filesystem::path& file, const Stage& stage);

double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace ls::capture
