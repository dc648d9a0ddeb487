#include "viewer/cpu_sources.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <utility>

#include "lightstage/errors.h"
#include "relight/lighting/half_relight.h"
#include "relight/lighting/relight.h"
#include "viewer/gl_util.h"
#include "viewer/view_lighting.h"

namespace ls::viewer {
namespace {

class CpuFieldSource : public GpuSource {
 public:
  // Half floats when their relit error allows (half the bytes a frame streams: about twice the
  // frame rate, bench_viewer).
  explicit CpuFieldSource(const capture::ReflectanceField& field)
      : field_(field), half_(relight::HalfField::of(field, 1e-3, &half_error_)), sources_(field) {}
  std::string name() const override { return "field"; }
  bool adds_bright_sources() const override { return true; }
  std::string shadows() const override { return sources_.shadows(); }
  std::string note() const override {
    char precision[96];
    if (half_) {
      std::snprintf(precision, sizeof precision, " (streamed in half float: %s, relit error %.1e)",
                    gl_util::mb(half_->bytes()).c_str(), half_error_);
    } else {
      std::snprintf(precision, sizeof precision, " (float: %s)",
                    half_error_ < 0 ? "this CPU has no F16C" : "half's relit error over 1e-3");
    }
    return "field: " + std::to_string(field_.num_lights()) + " LEDs, " +
           gl_util::mb(field_.bytes()) + precision +
           " in memory; software OpenGL: relit on the CPU and uploaded (faster than its shader)";
  }
  int width() const override { return field_.width(); }
  int height() const override { return field_.height(); }
  std::size_t bytes() const override { return 0; }
  void render(const ViewLighting& lighting, GpuTarget& target) override {
    gl_util::check_target(*this, target);
    gl_util::check_led_weights(*this, lighting.field_irradiance_rgb(), field_.num_lights());
    // The map by LED cells (without its bright sources when they were split off), then the
    // sources at their true directions.
    if (half_) {
      half_->relight_into(lighting.field_irradiance_rgb(), image_);
    } else {
      relight::relight_into(field_, lighting.field_irradiance_rgb(), image_);
    }
    sources_.add(lighting, image_);
    target.upload(image_);
  }

 private:
  const capture::ReflectanceField& field_;
  double half_error_ = 0;
  std::optional<relight::HalfField> half_;
  BrightSourceLight sources_;
  Image image_;
};

class CpuPcaSource : public GpuSource {
 public:
  explicit CpuPcaSource(relight::PcaField pca) : pca_(std::move(pca)), sources_(pca_) {}
  std::string name() const override { return pca_.name(); }
  bool adds_bright_sources() const override { return true; }
  std::string shadows() const override { return sources_.shadows(); }
  std::string note() const override {
    return pca_.name() + ": software OpenGL: relit on the CPU and uploaded";
  }
  int width() const override { return pca_.width(); }
  int height() const override { return pca_.height(); }
  std::size_t bytes() const override { return 0; }
  void render(const ViewLighting& lighting, GpuTarget& target) override {
    gl_util::check_target(*this, target);
    gl_util::check_led_weights(*this, lighting.field_irradiance_rgb(), pca_.num_lights());
    // As the field: the map without its bright sources by the LED cells, then the sources,
    // rendered from the PCA's own reconstruction.
    pca_.relight_led_weights_into(lighting.field_irradiance_rgb().data(), image_);
    sources_.add(lighting, image_);
    target.upload(image_);
  }

 private:
  relight::PcaField pca_;
  BrightSourceLight sources_;  // After pca_, which it reads.
  Image image_;
};

}  // namespace

bool software_renderer() {
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  if (renderer == nullptr) return false;
  for (const char* name : {"llvmpipe", "softpipe", "swrast"}) {
    if (std::strstr(renderer, name) != nullptr) return true;
  }
  return false;
}

std::unique_ptr<GpuSource> relight_field_on_cpu(const capture::ReflectanceField& field) {
  return std::make_unique<CpuFieldSource>(field);
}

std::unique_ptr<GpuSource> relight_pca_on_cpu(const relight::PcaField& pca) {
  return std::make_unique<CpuPcaSource>(pca);
}

}  // namespace ls::viewer
