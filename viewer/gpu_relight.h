#pragma once
// Relighting on the GPU: the viewer's sources (measured field, PCA-compressed field,
// fitted models) live in textures and a shader forms the image, so rotating the environment costs
// one small upload (the per-LED or per-basis weights) and one draw.
//
// Conventions are the CPU ones: output is linear radiance in field units, exactly what
// relight::relight (field), PcaField::relight_led_weights_into (PCA) and render_models (models)
// give for the same lighting; tests read the framebuffer back and compare with those.
//
// Precision and cost: FieldPrecision and the `precision` argument of upload_field (defaulted;
// benchmarks force half or float), GpuSource::bytes(); ModelShading and the `shading` argument of
// upload_models (defaulted: kExact).
// Bright sources: ViewLighting::split and field_irradiance_rgb(),
// GpuSource::adds_bright_sources(); field sources add the split-off sources
// (relight::FieldSources) to the cells' image.
//
// Everything here needs a current OpenGL 3.3 core context (viewer/gl_window.h) on the calling
// thread. Errors (shader compile, GL out of memory) throw ls::HardwareError with the GL message.
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"
#include "relight/sources/field_sources.h"

namespace ls::viewer {

// The lighting of one frame, in both forms the sources take.
struct ViewLighting {
  // 3 floats per LED of the field/PCA (E_l per channel, as integrate_environment gives). Field and
  // PCA sources use this (a field only when `split` is unset; with `split` set this may be empty
  // when no PCA is shown: viewer/view_lighting.h).
  std::vector<float> led_irradiance_rgb;
  // The same lighting as distant lights (LightingForModels::environment or ::directional). Model
  // sources use this.
  relight::LightingForModels lights;
  // A field under an environment map with compact sources (a sun, a small lamp), set
  // only when the map has some. Field sources relight by split->weights (the map without its
  // sources, by LED cells) and add each source at its true direction (relight::FieldSources::add),
  // as `lightstage relight` does. Sources that cannot add them back (PCA, models) keep
  // led_irradiance_rgb and lights: the whole map, sun included.
  std::optional<relight::SplitLighting> split;

  // What a field source relights by: split->weights.irradiance_rgb when set, else
  // led_irradiance_rgb.
  const std::vector<float>& field_irradiance_rgb() const {
    return split ? split->weights.irradiance_rgb : led_irradiance_rgb;
  }
};

// A float RGBA render target (texture + framebuffer) of a source's size, owned by the caller.
class GpuTarget {
 public:
  GpuTarget(int width, int height);
  ~GpuTarget();
  GpuTarget(const GpuTarget&) = delete;
  GpuTarget& operator=(const GpuTarget&) = delete;
  int width() const { return width_; }
  int height() const { return height_; }
  unsigned texture() const { return texture_; }  // GL_RGBA32F, linear radiance.
  unsigned framebuffer() const { return framebuffer_; }
  // glReadPixels into a 3-channel Image (row 0 at the top, as every Image).
  Image read_back() const;
  // The reverse: writes an image of the target's size (row 0 at the top; 1 channel is grey, extra
  // channels are ignored) into the texture, so that read_back() returns it.
  void upload(const Image& image);

 private:
  int width_ = 0, height_ = 0;
  unsigned texture_ = 0, framebuffer_ = 0;
};

class GpuSource {
 public:
  virtual ~GpuSource() = default;
  virtual std::string name() const = 0;  // "field", "pca k=16", "models".
  // How it lives on the GPU, shown in the viewer: "field: 150 LEDs, 472 MB in 2 texture arrays",
  // or "field needs 1.9 GB, over the 1 GB budget: showing PCA k=24 instead".
  virtual std::string note() const = 0;
  virtual int width() const = 0;
  virtual int height() const = 0;
  virtual std::size_t bytes() const = 0;  // GPU memory its textures take.
  // Whether it renders ViewLighting::split (a field: the map without its bright sources by cells
  // plus the sources); the others (PCA, a field over budget shown as PCA, models) use the whole
  // map's led_irradiance_rgb or lights.
  virtual bool adds_bright_sources() const { return false; }
  // What cast the bright sources' shadows in its last frame (BrightSourceLight::shadows); empty
  // when it adds none.
  virtual std::string shadows() const { return {}; }
  // Throws InputError when the lighting does not fit the source (LED count) or the target's size
  // is not the source's.
  virtual void render(const ViewLighting& lighting, GpuTarget& target) = 0;
};

// GPU memory a source may use: from GL_NVX_gpu_memory_info / GL_ATI_meminfo where present, else
// 1 GiB.
std::size_t gpu_memory_budget_bytes();

// How the field's values are stored. kAuto: half float (scaled by a power of two so the largest
// value sits well inside half's range) when that keeps a sample of pixels, relit under equal
// weights, within 1e-3 relative of float; else float. On a software renderer (llvmpipe) float is
// as fast or faster and exact, so it is used whenever it fits the budget. 478 MB in float, 239 MB
// in half at 512^2 x 150.
enum class FieldPrecision { kAuto, kHalf, kFloat };

// The field in textures (half float where that keeps the CPU result within tolerance; say which in
// note()). A field over `budget_bytes` is compressed (PCA, noise-floor rank, at most 64 and at
// most what fits the budget) and that is uploaded instead, with note() saying so; HardwareError
// when not even rank 1 fits. Under a lighting with bright sources (ViewLighting::split) the source
// computes their light on the CPU (relight::FieldSources, built from `field` the first time) and
// adds it in the shader, so `field` must then outlive the source.
std::unique_ptr<GpuSource> upload_field(const capture::ReflectanceField& field,
                                        std::size_t budget_bytes = gpu_memory_budget_bytes(),
                                        FieldPrecision precision = FieldPrecision::kAuto);
std::unique_ptr<GpuSource> upload_pca(const relight::PcaField& pca);

// How the models source shades: fitted BRDFs summed over the lights, or against a prefiltered
// environment.
//  * kExact: the BRDF summed over every distant light (relight/fit/model_render.h, line for line;
//    1.9e-5 of the peak from render_models). Cost is linear in the lights: 2.2 s a frame at 512^2
//    under 512 lights on llvmpipe.
//  * kPrefiltered: the lights turned, on the CPU, into (a) 9 spherical-harmonic coefficients of
//    irradiance per channel (Ramamoorthi & Hanrahan 2001), diffuse = albedo/pi * E(n); Oren-Nayar
//    as albedo/pi * E(n) * (A + B b(cos_o)), b its azimuthal factor's mean under uniform light
//    (exact under uniform light, the usual approximation otherwise); (b) a prefiltered
//    lat-long radiance stack, 64x32 per level, 8 levels of Beckmann roughness m (0.05 .. 1), each
//    the lights convolved with the Beckmann reflection lobe and normalised (a radiance), sampled
//    along the mirror direction (for Torrance-Sparrow leaning toward the normal with m, as
//    Frostbite's dominant direction) and multiplied by the lobe's directional albedo under unit
//    radiance (a table over cos_o and m, per lobe: Torrance-Sparrow, Phong with the map's
//    equivalent m): the split-sum approximation. No per-light work in the shader. The CPU work is
//    redone only when the lights change (a new rotation), not per frame.
//  * kAuto: kPrefiltered when the lighting has more than kMaxExactLights lights (an environment),
//    kExact otherwise (a point light, where exact is cheap and prefiltering would blur it). What
//    the viewer should use; not the default argument, so that callers that compare with
//    render_models at 2e-3 (viewer_app_test) keep the exact path until they opt in.
enum class ModelShading { kAuto, kExact, kPrefiltered };
inline constexpr int kMaxExactLights = 16;

std::unique_ptr<GpuSource> upload_models(const relight::ModelMaps& maps,
                                         const relight::ModelRenderOptions& options = {},
                                         ModelShading shading = ModelShading::kExact);

// Tone mapping for display: exposure (stops) and sRGB of the linear target into the bound
// framebuffer's viewport (drawn as a textured quad); `split`: optional second target shown right of
// the divider at x = divider (0..1); `difference`: show |a - b| scaled by 2^exposure instead
// (without a split target, difference shows the target as it is). The target fills the viewport
// (the caller keeps the aspect ratio); magnified pixels are shown as blocks (nearest).
struct DisplayOptions {
  double exposure_stops = 0.0;
  const GpuTarget* split = nullptr;
  double divider = 0.5;
  bool difference = false;
};
void draw_to_screen(const GpuTarget& target, const DisplayOptions& options, int viewport_x,
                    int viewport_y, int viewport_width, int viewport_height);

}  // namespace ls::viewer
