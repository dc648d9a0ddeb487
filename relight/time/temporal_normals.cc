// Normals refined over every step (relight/time/temporal_fit.h, refine_normals_over_steps): the
// geometry does not change over time, the reflectance does, so each step's samples at that step's
// own BRDF fit all constrain the one normal.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

// GCC 12 warns that TinySolver::Solve reads cost_ uninitialised with this 2-parameter problem: a
// false positive (Update() sets it before the read, and Solve returns early when Update fails).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include "relight/fit/pixel_solver.h"
#pragma GCC diagnostic pop

#include "physics/brdf.h"
#include "relight/time/temporal_fit.h"

namespace ls::relight {
namespace {

using pixel::Sample;

// One step of a pixel: its usable samples and that step's fitted BRDF parameters (physical).
struct StepSamples {
  int first = 0, count = 0;  // Into the pixel's sample buffer.
  double q[kTemporalParamCount];
};

// Residuals of every step's samples at the normal n0 tilted by two angles along t1, t2, each step
// rendered with its own parameters (Oren-Nayar diffuse + white Torrance-Sparrow lobe, as fit_step).
struct JointNormalCost {
  const std::vector<Sample>* samples;
  const std::vector<StepSamples>* steps;
  Eigen::Vector3d n0, t1, t2, wo;
  int residuals = 0;
  int NumResiduals() const { return residuals; }
  template <class T>
  bool operator()(const T* angles, T* r) const {
    using std::sqrt;
    const physics::brdf::Vec3<T> m =
        n0.cast<T>() + t1.cast<T>() * angles[0] + t2.cast<T>() * angles[1];
    const physics::brdf::Vec3<T> n = m / sqrt(m.dot(m));
    const physics::brdf::Vec3<T> view = wo.cast<T>();
    for (const StepSamples& s : *steps) {
      T q[kTemporalParamCount];
      for (int p = 0; p < kTemporalParamCount; ++p) q[p] = T(s.q[p]);
      const auto diffuse = [&](const physics::brdf::Geometry<T>& g) {
        return physics::brdf::oren_nayar(g, q[kParamSigma]);
      };
      const auto specular = [&](const physics::brdf::Geometry<T>& g) {
        return q[kParamKs] * physics::brdf::torrance_sparrow(g, q[kParamRoughness]);
      };
      pixel::sample_residuals(samples->data() + s.first, s.count, n, view, q, diffuse, specular,
                              r + 3 * s.first);
    }
    return true;
  }
};

}  // namespace

NormalMap refine_normals_over_steps(const std::vector<const capture::ReflectanceField*>& fields,
                                    const std::vector<StepFit>& fits, NormalMap normals,
                                    const TemporalFitOptions& options) {
  if (fields.size() < 2 || fields.size() != fits.size()) return normals;
  const capture::ReflectanceField& first = *fields.front();
  const int width = first.width(), height = first.height();
  std::vector<capture::ValidLights> valid;
  valid.reserve(fields.size());
  for (const auto* f : fields) valid.push_back(capture::valid_lights(*f));
  const NormalOptions& no = options.brdf.normals;
  const FitOptions& fo = options.brdf;
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Sample> samples;
    std::vector<StepSamples> steps;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        if (int(normals.flags.at(x, y, 0)) != 0) continue;
        samples.clear();
        steps.clear();
        for (size_t s = 0; s < fields.size(); ++s) {
          if (!(fits[s].sigma.at(x, y, 0) > 0)) continue;  // The step has no fit here.
          StepSamples step;
          step.first = int(samples.size());
          samples.resize(samples.size() + valid[s].index.size());
          step.count =
              pixel::gather_samples(*fields[s], valid[s], no, x, y, samples.data() + step.first)
                  .count;
          samples.resize(size_t(step.first) + size_t(step.count));
          for (int p = 0; p < kTemporalParamCount; ++p) step.q[p] = fits[s].value.at(x, y, p);
          steps.push_back(step);
        }
        // One step alone refines nothing the source step's own fit did not.
        if (steps.size() < 2) continue;
        JointNormalCost cost{&samples, &steps, {}, {}, {}, {}, int(3 * samples.size())};
        cost.n0 = pixel::normal_at(normals, x, y);
        cost.t1 = cost.n0.unitOrthogonal();
        cost.t2 = cost.n0.cross(cost.t1);
        cost.wo =
            pixel::view_dir_at(fo.view_dir_per_pixel, size_t(first.first_row() + y) * width + x);
        const Eigen::Vector2d start(0, 0);
        const double before = pixel::chi2_at(cost, start.data());
        const pixel::SolveResult<2> solved = pixel::solve(cost, start, fo.max_iterations);
        if (!solved.usable() || !(solved.chi2 < before)) continue;
        const Eigen::Vector3d n =
            (cost.n0 + cost.t1 * solved.x(0) + cost.t2 * solved.x(1)).normalized();
        // A normal turned away from the camera is not a surface the camera sees.
        if (!n.allFinite() || n.dot(cost.wo) <= 0) continue;
        for (int c = 0; c < 3; ++c) normals.normal.at(x, y, c) = float(n(c));
      }
    }
  });
  return normals;
}

}  // namespace ls::relight
