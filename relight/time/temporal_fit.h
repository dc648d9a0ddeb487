#pragma once
// Time-varying BRDFs (Sun, Sunkavalli, Ramamoorthi, Belhumeur, Nayar 2007): from one
// reflectance field per time step of the same scene, per pixel
//   1. one normal for all steps (photometric stereo, relight/fit/normals.h, on the last,
//      driest step by default: see NormalSource), held fixed: the geometry does not change;
//   2. per step, the full BRDF with that normal: Oren-Nayar diffuse (albedo RGB, sigma) + white
//      Torrance-Sparrow lobe (k_s, Beckmann roughness), samples and noise weighting as in
//      relight/fit/fit.h. Always the full model, never a per-step model choice, so every step gives
//      the same six parameters; what stays constant over time is decided by the temporal model
//      choice. Each parameter's uncertainty comes from the fit's Jacobian: cov = (J^T J)^-1
//      (residuals are already divided by the measured noise) scaled by max(1, reduced chi^2) so a
//      misfit widens it, with a floor (kParamSigmaFloor) standing for model error;
//   3. over time, one process per pixel shared by its six parameters (as in the paper: one rate,
//      one onset), each parameter with its own wet (start) and dry (end) value:
//        constant     p(t) = dry
//        exponential  p(t) = wet before the onset, then dry + (wet - dry) e^(-lambda (t - onset))
//        sigmoid      p(t) = wet + (dry - wet) / (1 + e^(-kappa (t - onset)))
//        dust         the exponential with k_s decaying to 0 and sigma, roughness constant
//                     (rho(tau) = (1 - T) rho_dust + T rho_d + e^(-lambda tau) rho_s, T =
//                     e^(-lambda tau)): the dust colour is the dry albedo.
//      Each is fitted by bounded weighted least squares (ceres::TinySolver, autodiff; the rate and
//      onset bounds are built into the parametrisation), started from a grid over (rate, onset)
//      with the endpoints solved linearly at each grid point (they are linear given the shape).
//      The simplest model by BIC = chi^2 + k ln(n) (n: residuals used; ties to the simpler) wins,
//      the criterion of relight/fit/fit.h. A model with as many parameters per series as usable
//      steps or more (constant 1, exponential/sigmoid/dust 4) is not considered (flag
//      kTooFewSteps);
//   4. the chosen model kept only where it predicts the steps left out of its fit at least as
//      well as interpolating the per-step fits does (hold_out_steps), else those fits (kSteps):
//      in-sample BIC alone lets a model that misses the data win over the data;
//   5. a modelled pixel renders its model plus each step's significant departure from it,
//      interpolated between steps (TemporalMaps::step_values): at a captured step, what was
//      captured there wherever that stands out of its noise.
//
// Times are seconds of scene time (ReflectanceField::scene_time_s). Rates are 1/s. The rate is
// bounded by max_rate_times_interval / (smallest step interval): a faster process is a step
// between two samples, its rate is only a lower bound (flag kFasterThanSampling).
#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/exr_channels.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"

namespace ls::relight {

enum class TemporalModel : int {
  kNone = 0,  // Flagged: not fitted.
  kConstant = 1,
  kExponential = 2,
  kSigmoid = 3,
  kDust = 4,
  // A data-driven curve (TemporalMaps::curves) through a per-pixel time warp.
  kCurve = 5,
  // The per-step fits themselves (TemporalMaps::step_values), interpolated linearly in time in
  // the space a render sees (as the curves'): where no model predicts the steps it was not given
  // better than this does (hold_out_steps). Rate edits warp its time; it is never a transfer's
  // source.
  kSteps = 6,
};
const char* to_string(TemporalModel model);
inline constexpr int kTemporalModelCount = 7;

// The per-step BRDF parameters, in order.
enum TemporalParam : int {
  kParamAlbedoR = 0,
  kParamAlbedoG,
  kParamAlbedoB,
  kParamSigma,      // Oren-Nayar sigma, radians, [0, pi/2].
  kParamKs,         // White Torrance-Sparrow k_s, >= 0.
  kParamRoughness,  // Beckmann m, [0.02, 1].
  kTemporalParamCount,
};
// "albedo.r", "albedo.g", "albedo.b", "sigma", "ks", "roughness".
const char* temporal_param_name(int param);
// Smallest per-step standard deviation of each parameter (model error; relative noise alone would
// claim more than the BRDF model can deliver).
inline constexpr double kParamSigmaFloor[kTemporalParamCount] = {0.003, 0.003, 0.003,
                                                                 0.01,  0.003, 0.005};

// Bit codes in the flags channel (0 = ok).
enum TemporalFlag : int {
  kTemporalNoNormal = 1,      // Normal flagged (background, too few lights): not fitted.
  kTooFewSteps = 2,           // Some models were not considered (too few usable steps).
  kStepDropped = 4,           // At least one step was unusable here (dead LEDs, failed fit).
  kFasterThanSampling = 8,    // Rate at its bound: a step between two samples; rate is a bound.
  kTemporalFitFailed = 16,    // No temporal model could be fitted (no usable step).
  kOnsetAtCaptureStart = 32,  // The process was already running at the first step.
  kExtrapolated = 64,         // (render_temporal only) t outside the captured steps.
  // A solver stopped on its iteration limit: the chosen temporal model's fit (max_iterations) or
  // the chosen per-step BRDF fit of a used step (brdf.max_iterations); the values are where LM
  // stopped, not at a minimum. The bit of kFitNotConverged (fit.h): models_at_time carries it.
  kTemporalNotConverged = 128,
  // The best-fitting process ran away from the data: an endpoint far outside what the steps show
  // (beyond their range by more than that range and 3 sigma), an onset at the last step, or a
  // rate the captured span cannot show (rate x span < kMinRateTimesSpan). The model stays in the
  // maps for inspection; the pixel renders from its nearest per-step fit
  // (TemporalMaps::step_values), never from the runaway model.
  kTemporalDegenerate = 256,
};
inline constexpr double kMinRateTimesSpan = 0.1;
static_assert(kTemporalNotConverged == kFitNotConverged);

// Measured on the simulator's time-varying scene (tests/time, 40 LEDs, 10 steps): mean normal
// error pooled 0.73, first 0.71, last 0.58 degrees. The wet steps have the strongest, sharpest
// lobes, which bias photometric stereo; pooling averages that in and mixes changing albedos.
enum class NormalSource {
  kPooled,  // One field with every step's lights side by side.
  kFirst,   // The first step's field (the wettest).
  kLast,    // The last step's field (the driest): the default.
};

struct TemporalFitOptions {
  // Noise, shadow thresholds, roughness starts, k_s bound of the per-step fits (refine_normal is
  // ignored: the normal is always held fixed). brdf.readmit_dim_samples readmits the dim samples
  // in the source step's normals and in every step's fit (FitOptions says why): the rise-and-fall
  // lapse at a fifth of the exposure, 7 of 13 steps captured, relative error at the captured steps
  // 0.141 -> 0.056 (the photographs 0.089), held out 0.169 -> 0.130 (tests/relight/time/
  // temporal_curves_test.cc). Off by default: at full exposure with 5 of 25 steps captured, the
  // curves learnt from the changed step fits miss the held-out steps (0.12 -> 0.21; linear
  // interpolation 0.125), and leaving one step out of a pixel's fit does not leave it out of the
  // curves, so the model choice keeps them.
  FitOptions brdf;
  NormalSource normal_source = NormalSource::kLast;
  // Refine the photometric-stereo normals by each pixel's full BRDF fit (relight/fit/fit.h, its
  // own model, refine_normal) on that step: photometric stereo is biased by a lobe and noisy on
  // dark materials (the rise-and-fall scene's corroding metal, albedo 0.06: 3.4 degrees mean
  // error from the driest step, 1.1 refined).
  bool refine_normals = true;
  // Then refine each normal over every step at once, each step rendered by its own fit, and fit
  // the steps again at the refined normals; this many rounds (0: the source step's normal).
  int normal_rounds_over_steps = 2;
  bool fit_exponential = true;
  bool fit_sigmoid = true;
  bool fit_dust = true;
  double max_rate_times_interval = 4.0;  // lambda, kappa <= this / smallest step interval.
  int max_iterations = 60;  // Per temporal model fit (brdf.max_iterations: per step fit).
  // Learn data-driven curves (TemporalCurves) and offer them to every pixel.
  bool fit_curves = true;
  // Keep a pixel's model only where it predicts each step left out of its fit at least as well as
  // interpolating the neighbouring steps' fits does; elsewhere the per-step fits (kSteps).
  bool hold_out_steps = true;
  // Phase "fit over time", rows (each step's fit, then the models'): called as rows finish, from
  // worker threads; must be thread-safe.
  ProgressFn progress;
  std::string validate() const;
};

// Per step, per pixel BRDF parameters and their standard deviations (both kTemporalParamCount
// channels; sigma is 0 where the step is unusable at that pixel).
struct StepFit {
  double time_s = 0;
  Image value;
  Image sigma;
  // 1 channel: kTemporalNotConverged where the chosen per-step fit stopped on its iteration
  // limit, else 0. Empty: no such information (treated as 0).
  Image flags;
  // kRenderedCount channels: the standard deviations of what a render sees (RenderedParam) from
  // the fit's joint covariance: a fit trades k_s against m along the lobe's peak, and the albedo
  // against Oren-Nayar's sigma along albedo * A(sigma), both measured far better than their
  // parts. Empty: propagated from the parameters' own deviations.
  Image rendered_sigma;
  int valid_lights = 0;
};

// Curves follow what a render sees (a curve per parameter loses what one step's fit couples):
// the albedo as albedo * A(sigma) (physics::brdf::oren_nayar_a; = albedo for Lambert), sigma, k_s
// as the lobe's peak k_s / m^2 (1/sr) and the roughness as 1/m; at time t m(t) = 1 / curve,
// albedo(t) = curve / A(sigma(t)), k_s(t) = curve m(t)^2. A curve pixel's wet and dry channels hold
// its endpoints in that space (unclamped: a curve's extreme may lie outside the span it was fitted
// on). The processes keep the BRDF's parameters: their closed forms are in them.
enum RenderedParam : int {
  kRenderedAlbedoR = 0,
  kRenderedAlbedoG,
  kRenderedAlbedoB,
  kRenderedPeak,
  kRenderedCount
};

// Channels of TemporalMaps::maps, in order.
enum TemporalChannel : int {
  kTNormalX = 0,
  kTNormalY,
  kTNormalZ,
  kTModel,  // TemporalModel as a number.
  kTRate,   // lambda (exponential, dust) or kappa (sigmoid), 1/s; 0 for constant.
  kTOnset,  // Onset (exponential, dust: start of the decay; sigmoid: midpoint), seconds.
  kTWet,    // kTemporalParamCount channels: wet.albedo.r ... wet.roughness.
  kTDry = kTWet + kTemporalParamCount,         // dry.albedo.r ... dry.roughness.
  kTConfidence = kTDry + kTemporalParamCount,  // BIC weight of the chosen model.
  kTResidual,   // Reduced chi^2 of the chosen model over the per-step parameters.
  kTStepsUsed,  // Usable steps at this pixel.
  kTFlags,      // TemporalFlag bits.
  kTCurve,      // kCurve: the curve family (TemporalMaps::curves) it follows; 0 otherwise.
  // kCurve: the curve position tau its last captured step reached (from its first's on, its steps
  // saw the curve up to here). Renders hold tau within what the steps saw: a time edit that
  // speeds the pixel up holds its last seen state rather than making up one it never showed.
  kTCurveSeen,
  kTemporalChannelCount,
};
const std::vector<std::string>& temporal_channel_names();

struct TemporalSummary {
  int pixels = 0;
  int fitted = 0;
  int flagged = 0;         // Not fitted: no_normal + no_usable_step.
  int no_normal = 0;       // kTemporalNoNormal: background, too few lit lights.
  int no_usable_step = 0;  // kTemporalFitFailed: no step's fit usable, or no model fitted.
  int per_model[kTemporalModelCount] = {0, 0, 0, 0, 0, 0, 0};
  int faster_than_sampling = 0;
  int too_few_steps = 0;
  int step_dropped = 0;
  int not_converged = 0;        // Fitted pixels flagged kTemporalNotConverged.
  int degenerate = 0;           // Fitted pixels flagged kTemporalDegenerate.
  int curve_families = 0;       // TemporalMaps::curves.size().
  double seconds_steps = 0;     // Per-step BRDF fits.
  double seconds_temporal = 0;  // Temporal model fits.
  std::string to_string() const;
};

// Data-driven temporal curves (after Gu, Tu, Ramamoorthi, Belhumeur, Matusik, Nayar
// 2006, "Time-varying surface appearance: acquisition, modeling and rendering"): one curve per
// BRDF parameter, shared by the surface, free to rise and fall; per pixel a time warp and its own
// endpoints:
//   p(t) = dry + (wet - dry) phi_p(tau),  tau = clamp(rate (t - onset), 0, 1)
// A scene's materials change differently, so the curves come in families (one per way of
// changing; the paper has one per material): each pixel follows one family (channel kTCurve).
// phi_p runs over [0, 1] (its smallest knot 0, its largest 1), through its knots at evenly spaced
// tau (Catmull-Rom), so "wet" is the parameter where the curve peaks and "dry" where it bottoms.
// Learnt from the pixels no process explains (alternating: the knots by linear least squares
// given every pixel's warp and endpoints, then each pixel's warp by a grid with its endpoints
// linear); a further family is learnt from the pixels the families so far leave unexplained, and
// the pixels are then shared among the families (each learnt again from its own) as in k-means.
// Offered to the pixels no process explains and to those whose process misses the albedo a
// render sees (albedo A(sigma), where the steps' fits trade one against the other); BIC chooses
// by strong evidence (6), with the same parameter count as the exponential (rate, onset, wet and
// dry of six parameters), so a process the data follow keeps the pixel.
struct TemporalCurves {
  std::vector<std::vector<double>> knots;  // kTemporalParamCount curves, or none.
  bool empty() const { return knots.empty(); }
  // phi_p(tau), tau clamped to [0, 1].
  double at(int p, double tau) const;
  // The weights of the (up to four) knots that phi(tau) sums for n knots: first index and weights.
  static int weights(double tau, int n, double w[4]);
};

struct TemporalMaps {
  Image maps;  // kTemporalChannelCount named channels.
  std::vector<double> step_times_s;
  // What each fitted pixel renders at the captured steps (step i's parameter p in channel
  // i * kTemporalParamCount + p, named "step.I.<param>"): a kSteps or degenerate pixel's per-step
  // fits (a step unusable at the pixel holds its nearest usable step's); a modelled pixel's model
  // at the step plus its per-step fit's significant departure from it (significant_departure),
  // which a render between two steps interpolates onto the model: a captured step renders as its
  // fit wherever that fit stands out of its noise, the model smooths the noise elsewhere, and an
  // editor starts from the material captured (the rise-and-fall lapse, 3 of 25 steps captured:
  // relative error at the captured steps 0.026 -> 0.013, the per-step fits' 0.013). 0 at unfitted
  // pixels; empty when no pixel is fitted.
  Image step_values;
  // Whether step_values holds the modelled pixels' steps too: files before them hold only the
  // kSteps and degenerate pixels', and their modelled pixels render from the model alone.
  bool modelled_steps = false;
  // In memory only: the time scale a rate edit gave each modelled pixel (row-major; empty: 1 at
  // every pixel), which its steps' departures follow as its model does.
  std::vector<float> edited_time_scale;
  // The curve families of the pixels whose model is kCurve; stored in the attribute.
  std::vector<TemporalCurves> curves;
  // Pixel (x, y)'s family when its model is kCurve, else null.
  const TemporalCurves* curves_at(int x, int y) const;
  NoiseModel noise;
  std::string noise_source;
  TemporalSummary summary;
  double first_time_s() const { return step_times_s.empty() ? 0 : step_times_s.front(); }
  double last_time_s() const { return step_times_s.empty() ? 0 : step_times_s.back(); }
  float at(int x, int y, int c) const { return maps.at(x, y, c); }
  TemporalModel model(int x, int y) const { return TemporalModel(int(maps.at(x, y, kTModel))); }
};

// The fields sorted by scene_time_s; InputError naming the file when their sizes differ, a time
// is not finite or two share a time.
std::vector<const capture::ReflectanceField*> steps_by_time(
    std::vector<const capture::ReflectanceField*> steps);
// The fixed normals and each step's BRDF fit at them (steps sorted by time): estimate_normals on
// the source the options name, refined by each pixel's BRDF fit on that step
// (options.refine_normals), then normal_rounds(...) times refined over every step at once
// (refine_normals_over_steps) and the steps fitted again. rows_done: after each step's fit.
struct NormalsAndStepFits {
  NormalMap normals;
  std::vector<StepFit> steps;
};
NormalsAndStepFits fit_normals_and_steps(
    const std::vector<const capture::ReflectanceField*>& sorted, const TemporalFitOptions& options,
    const std::function<void(int rows)>& rows_done = {});
// The rounds of refinement over every step fit_normals_and_steps makes for `steps` steps.
int normal_rounds(const TemporalFitOptions& options, int steps);
// fit_normals_and_steps' normals (steps in any order).
NormalMap estimate_temporal_normals(const std::vector<capture::ReflectanceField>& steps,
                                    const TemporalFitOptions& options);
// Each pixel's normal refined by Gauss-Newton on the residuals of every step at once, each step
// rendered by its own fit (`fits`, one per field, in the same order): the geometry is the same at
// every step, so a dark or glossy pixel that one step pins down poorly is pinned down by all.
NormalMap refine_normals_over_steps(const std::vector<const capture::ReflectanceField*>& fields,
                                    const std::vector<StepFit>& fits, NormalMap normals,
                                    const TemporalFitOptions& options);
// Per-step BRDF fits with fixed normals.
StepFit fit_step(const capture::ReflectanceField& field, const NormalMap& normals,
                 const TemporalFitOptions& options);
// Temporal models from per-step fits (sorted by time, at least one).
TemporalMaps fit_temporal_models(const std::vector<StepFit>& steps, const NormalMap& normals,
                                 const TemporalFitOptions& options);
// Step 3 in pieces that also run on bands of rows (`lightstage fit --time` on fields
// larger than memory). All but the curves is per pixel; fit_temporal_models is these on one band:
//   1. fit_temporal_processes on each band's per-step fits;
//   2. a CurveSample: count() over every band's maps, then gather() over every band, in order,
//      then learn() the curves (when options.fit_curves);
//   3. offer_temporal_curves and count_temporal_models on each band.
// The processes of the pixels of `steps` (a band or the whole image) chosen by BIC, each pixel's
// BIC in best_bic (HUGE_VAL where none was fitted); summary: pixels, fitted, flagged.
TemporalMaps fit_temporal_processes(const std::vector<StepFit>& steps, const NormalMap& normals,
                                    const TemporalFitOptions& options,
                                    std::vector<double>& best_bic);
namespace temporal_internal {
struct Series;
}
// The pixels the curves learn from: an evenly strided sample (at most 1500) of those no process
// explains, in the order the bands are visited.
class CurveSample {
 public:
  CurveSample();
  ~CurveSample();
  CurveSample(const CurveSample&) = delete;
  CurveSample& operator=(const CurveSample&) = delete;
  void count(const Image& maps);
  void gather(const std::vector<StepFit>& steps, const Image& maps);
  // The curve families; none when too few pixels are unexplained or the steps span no time.
  std::vector<TemporalCurves> learn(const std::vector<double>& step_times) const;

 private:
  size_t candidates_ = 0, gathered_ = 0;
  std::vector<temporal_internal::Series> series_;
};
// The curves offered to every pixel of `band` a process leaves unexplained (or whose process
// misses the albedo a render sees), and written where they win; band.curves = curves.
void offer_temporal_curves(const std::vector<StepFit>& steps, const std::vector<double>& best_bic,
                           const std::vector<TemporalCurves>& curves, TemporalMaps& band);
// Model choice that cannot lose to the data (options.hold_out_steps), on a band after the curves
// were offered: per pixel whose process leaves its steps unexplained (reduced chi^2 above 4) and
// per curve pixel (a curve learnt from the steps can pass through them), each
// interior usable step is left out in turn, the pixel's model fitted again
// without it (a process refined from its fit, a curve of its family, the constant) and its
// prediction at that step (with its departures at the neighbouring steps) compared with the linear
// interpolation of its neighbouring steps' fits (the nearest one's at either end), both in the
// space a render sees (the curves'), weighted by the left-out fit's deviations, the model's misfit
// at the captured steps beyond their noise added to its side. Where interpolation wins by strong
// evidence (a chi^2 difference above 6) the pixel takes kSteps; its confidence is then the weight
// of interpolation against the model, exp(-chi^2 / 2) of each, and its residual the held-out chi^2
// per sample.
void hold_out_steps(const std::vector<StepFit>& steps, const TemporalFitOptions& options,
                    TemporalMaps& band);
// `maps` with every fitted pixel rendering from its per-step fits (kSteps, time scale 1; a
// degenerate flag cleared): the per-step fits alone, the baseline the model choice is held to.
TemporalMaps every_pixel_from_its_steps(TemporalMaps maps, const std::vector<StepFit>& steps);
// The band's model and flag counts into its summary, and the step values of its pixels that
// render from them (degenerate, kSteps).
void count_temporal_models(const std::vector<StepFit>& steps, TemporalMaps& band);
// All of it. Fields must share size and lights (same LED ids, in order); they are sorted by
// scene_time_s, and two with the same time are an InputError.
TemporalMaps fit_temporal(const std::vector<capture::ReflectanceField>& steps,
                          const TemporalFitOptions& options);

// One pixel's temporal curve of one parameter at time t (no clamping to bounds); `curves` and p
// for kCurve.
double temporal_value(TemporalModel model, double rate, double onset, double wet, double dry,
                      double t, const TemporalCurves* curves = nullptr, int p = 0);

// One EXR with named channels + the step times and noise in the "lightstage:temporal" attribute,
// and PNG previews beside it: <stem>.model.png, .rate.png, .onset.png, .wet_albedo.png,
// .dry_albedo.png, .confidence.png, .flags.png.
void write_temporal_maps(const std::filesystem::path& path, const TemporalMaps& maps,
                         const ExrAttributes& attributes = {});
// The same file and previews written a band of rows at a time, top to bottom (a fit in bands):
// the same bytes as write_temporal_maps. `header` gives what the file's header holds
// (step times, noise, curves); step_values: whether the file has the step.I.<param> channels (a
// band without degenerate pixels writes zeros there); max_rate: the largest kTRate of the maps,
// for the rate preview. Nothing is left at `path` before commit().
class TemporalMapsWriter {
 public:
  TemporalMapsWriter(const std::filesystem::path& path, int width, int height,
                     const TemporalMaps& header, bool step_values, double max_rate,
                     const ExrAttributes& attributes = {});
  ~TemporalMapsWriter();
  TemporalMapsWriter(const TemporalMapsWriter&) = delete;
  TemporalMapsWriter& operator=(const TemporalMapsWriter&) = delete;
  // The next rows: band.maps and band.step_values (or none) of the same rows.
  void write_rows(const TemporalMaps& band);
  void commit();

 private:
  int step_channels_;
  std::unique_ptr<ImageRowWriter> maps_;
  std::vector<std::unique_ptr<PreviewRowWriter>> previews_;
};
// The largest rate (kTRate) of temporal maps.
double max_temporal_rate(const Image& maps);
// Reads what write_temporal_maps wrote; InputErrors name the file and the channel.
TemporalMaps read_temporal_maps(const std::filesystem::path& path);
// Rows [y0, y1) of the file (y1 < 0: to the last), checked as above (errors give the file's
// coordinates): a band of maps larger than memory; their summary counts the band's pixels.
TemporalMaps read_temporal_map_rows(const std::filesystem::path& path, int y0, int y1);

}  // namespace ls::relight
