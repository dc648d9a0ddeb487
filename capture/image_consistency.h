#pragma once
// The images of a one-light-at-a-time set checked against one another: each image against what
// the other images predict at its light, so that a glitched photograph (misregistered, from
// another light, black) is found and left out of the field before it biases the normals and
// fits, as the capture's own frames are checked on arrival (lightstage/controller/frame_checks.h).
//
// The prediction: per pixel, a quadratic in the light direction fitted by least squares to the
// images of the twelve lights nearest the image's (itself left out), every image clipped at twice
// its pixel's median over the set (highlights would decide the comparison alone). Shadows and
// highlights are not smooth in the direction, so an image is not judged pixel by pixel but by
// OpenCV's enhanced correlation coefficient (findTransformECC, translation only) with its
// prediction: the shift that aligns the two, and how well they correlate once aligned.
// - shifted: aligned, the image is `max_shift_px` or more away from its prediction (and the
//   shift explains it: moved, it fits about as well as its neighbours, or four times better than
//   as it is);
// - another light's: it correlates far better with what the others predict at another light
//   (beyond 1.5 times the spacing to its nearest light: a swap of neighbouring lights is not told
//   from the set's own calibration error); or aligned by a shift it still fits worse than the
//   images lit near it; or, unexplained, its misfit (1 - correlation) is max_misfit_ratio times
//   theirs;
// - black: its mean is below 1/1000 of the median image's.
// Flagged images are left out of the prediction and every image judged again, until no verdict
// changes (at most six rounds): a run of bad images (a fifth of the set) does not hide itself.
#include <Eigen/Core>
#include <string>
#include <vector>

namespace ls::capture {

// The images of a set at the size the check works at: grey (the mean of RGB), area-averaged so
// that the stack holds at most kMaxSamples values (and an image at most kMaxImagePixels).
class ConsistencyStack {
 public:
  // 128 MiB of floats (the check holds as much again: every image's prediction).
  static constexpr std::size_t kMaxSamples = std::size_t(1) << 25;
  static constexpr std::size_t kMaxImagePixels = std::size_t(1) << 19;
  // Images of width x height pixels, one per direction (unit, toward the light).
  ConsistencyStack(int width, int height, std::vector<Eigen::Vector3d> dirs);
  // Light `light`'s image (width * height * 3 floats, RGB innermost). Distinct lights may be
  // added from several threads at once.
  void add(int light, const std::vector<float>& rgb);

  int lights() const { return int(dirs_.size()); }
  int width() const { return width_; }     // Of the check's images.
  int height() const { return height_; }   //
  double scale() const { return scale_; }  // Pixels of the set's images per pixel of the check's.
  const std::vector<Eigen::Vector3d>& dirs() const { return dirs_; }
  const std::vector<float>& image(int light) const { return images_[std::size_t(light)]; }
  std::vector<float>& image(int light) { return images_[std::size_t(light)]; }
  bool has(int light) const { return !images_[std::size_t(light)].empty(); }

 private:
  int source_width_, source_height_;
  int width_, height_;
  double scale_;
  std::vector<Eigen::Vector3d> dirs_;
  std::vector<std::vector<float>> images_;
};

enum class ImageProblemKind { kShifted, kOtherLight, kBlack, kUnexplained };

// One image of a set as the check judged it.
struct ImageVerdict {
  bool flagged = false;
  ImageProblemKind kind = ImageProblemKind::kOtherLight;
  double shift_x_px = 0, shift_y_px = 0;  // Of the image against its prediction, source pixels.
  double correlation = 0;                 // With its prediction, once aligned.
  double misfit_ratio = 0;  // 1 - correlation over the usual near its light (1: typical).
  std::string reason;       // Flagged: a sentence saying why, with the figures.
};

struct ConsistencyOptions {
  // Pixels of the check's images (the set's, area-averaged to at most kMaxImagePixels). On a
  // smooth object the prediction's own error aligns clean images by up to 1.4 px (the DiLiGenT
  // ball), so a misregistration below this is not told from it; that error is in the check's
  // pixels, so on a set downsized for the check the threshold in the set's pixels grows with it
  // (a 12-megapixel frame: 7 px).
  double max_shift_px = 1.5;
  // Over the usual misfit of the images lit near it, for an image nothing else explains. Clean
  // real sets reach 10 (DiLiGenT reading, its corner lights) and 15 (the RTI lion, 64 x 43 px).
  double max_misfit_ratio = 20.0;
};

struct ConsistencyReport {
  std::vector<ImageVerdict> images;  // One per light of the stack.
  std::string not_checked;           // Why the set could not be checked ("" when it was).
  int rounds = 0;                    // Of judging every image against the others.
  std::vector<int> flagged() const;  // The lights flagged, in order.
};

// Fewer images than this leave a set unchecked: each prediction fits six terms to the twelve
// nearest images, which in a sparser dome span half of it (a 24-light sphere's grazing images
// then read as shifted).
constexpr int kMinImagesToCheck = 32;

// Clips the stack's images in place (at twice each pixel's median over the set, see above): they
// are the check's own.
ConsistencyReport check_image_consistency(ConsistencyStack& stack,
                                          const ConsistencyOptions& options = {});

}  // namespace ls::capture
