// GPU relighting (viewer/gpu_relight.h) against the CPU for the same inputs: the field and its PCA
// under an environment map and a point light, read back from the framebuffer; the budget's
// fallback, errors, drawing to the screen and the no-display error. Runs on llvmpipe under Xvfb
// (tests/viewer/with_xvfb.sh starts one per binary).
#include "viewer/gpu_relight.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>
#include <optional>
#include <string>

#include "lightstage/errors.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/fit.h"
#include "relight/lighting/half_relight.h"
#include "relight/lighting/relight.h"
#include "tests/viewer/gpu_relight_fixture.h"
#include "viewer/cpu_sources.h"
#include "viewer/gl_window.h"

namespace ls::viewer {
namespace {

using namespace gpu_testing;  // NOLINT(google-build-using-namespace)

Image cpu_field(const capture::ReflectanceField& field, const ViewLighting& lighting) {
  Image out;
  relight::relight_into(field, lighting.led_irradiance_rgb, out);
  return out;
}

TEST_F(GpuRelight, FieldInFloatAndHalfMatchesTheCpu) {
  for (const FieldPrecision precision : {FieldPrecision::kFloat, FieldPrecision::kHalf}) {
    const auto source = upload_field(*field_, std::size_t(1) << 30, precision);
    std::cout << source->note() << "\n";
    EXPECT_EQ(source->name(), "field");
    EXPECT_NE(source->note().find(precision == FieldPrecision::kHalf ? "half" : "float"),
              std::string::npos);
    for (const ViewLighting& lighting : {environment(0), environment(137), point_light()}) {
      const ImageDifference d =
          difference(gpu_render(*source, lighting), cpu_field(*field_, lighting));
      std::cout << "field " << (precision == FieldPrecision::kHalf ? "half" : "float") << ": max "
                << d.max_relative << ", mean " << d.mean_relative << "\n";
      if (precision == FieldPrecision::kFloat) {
        // Only the summation order differs. Measured max 1.6e-7, mean 7.7e-8.
        EXPECT_LT(d.max_relative, 1e-5);
        EXPECT_LT(d.mean_relative, 1e-5);
      } else {
        // Half keeps 11 bits: 2.4e-4 relative per value at most. Measured max 2.8e-4 (of the
        // peak), mean 1.8e-4.
        EXPECT_LT(d.max_relative, 1e-3);
        EXPECT_LT(d.mean_relative, 5e-4);
      }
    }
  }
}

TEST_F(GpuRelight, AutomaticPrecisionMeasuresHalfAndPrefersFloatOnLlvmpipe) {
  const auto source = upload_field(*field_);
  std::cout << source->note() << "\n";
  // Half keeps the sampled relit error under 1e-3 (measured 2.2e-4), so it would be chosen, but
  // on a software renderer (these tests run on llvmpipe) float is faster and fits the budget.
  EXPECT_NE(source->note().find("<= 1e-3"), std::string::npos) << source->note();
  const bool software = window_->renderer().find("llvmpipe") != std::string::npos;
  EXPECT_EQ(source->bytes(), std::size_t(64) * 48 * 40 * 3 * (software ? 4 : 2)) << source->note();
}

TEST_F(GpuRelight, PcaMatchesTheCpuGlobalAndTiled) {
  for (const int tile_size : {0, 16}) {
    relight::PcaOptions options;
    options.rank = 12;
    options.tile_size = tile_size;
    const relight::PcaField pca = relight::PcaField::build(*field_, options);
    const auto source = upload_pca(pca);
    std::cout << source->note() << "\n";
    EXPECT_EQ(source->name(), "pca k=12");
    for (const ViewLighting& lighting : {environment(45), point_light()}) {
      Image cpu;
      pca.relight_led_weights_into(lighting.led_irradiance_rgb.data(), cpu);
      const ImageDifference d = difference(gpu_render(*source, lighting), cpu);
      std::cout << "pca tile " << tile_size << ": max " << d.max_relative << ", mean "
                << d.mean_relative << "\n";
      // Float both sides, k = 12 terms. Measured 0 on llvmpipe (same summation order).
      EXPECT_LT(d.max_relative, 1e-5);
      EXPECT_LT(d.mean_relative, 1e-5);
    }
  }
}

// The software-renderer path (viewer/cpu_sources.h): the CPU result, uploaded and read back
// through the same target, row order included.
TEST_F(GpuRelight, CpuSourcesUploadTheCpuRelightingExactly) {
  EXPECT_EQ(software_renderer(), window_->renderer().find("llvmpipe") != std::string::npos);
  relight::PcaOptions options;
  options.rank = 12;
  const relight::PcaField pca = relight::PcaField::build(*field_, options);
  const auto field_source = relight_field_on_cpu(*field_);
  const auto pca_source = relight_pca_on_cpu(pca);
  EXPECT_NE(field_source->note().find("CPU"), std::string::npos);
  // The field is streamed in half floats where their relit error allows (HalfField): the upload
  // is that relighting exactly, and within half's 1e-3 of the float one.
  const std::optional<relight::HalfField> half = relight::HalfField::of(*field_);
  for (const ViewLighting& lighting : {environment(137), point_light()}) {
    const Image uploaded = gpu_render(*field_source, lighting);
    Image expected = cpu_field(*field_, lighting);
    EXPECT_LT(difference(uploaded, expected).max_relative, 1e-3);
    if (half) half->relight_into(lighting.led_irradiance_rgb, expected);
    EXPECT_EQ(difference(uploaded, expected).max_relative, 0.0);
    Image cpu;
    pca.relight_led_weights_into(lighting.led_irradiance_rgb.data(), cpu);
    EXPECT_EQ(difference(gpu_render(*pca_source, lighting), cpu).max_relative, 0.0);
  }
  ViewLighting wrong = environment(0);
  wrong.led_irradiance_rgb.pop_back();
  GpuTarget target(field_->width(), field_->height());
  EXPECT_THROW(field_source->render(wrong, target), InputError);
}

TEST_F(GpuRelight, FieldOverTheBudgetFallsBackToPcaAndSaysSo) {
  // The field needs 737 kB in half; 300 kB hold 8 ranks of float coefficients (36.9 kB each).
  const auto source = upload_field(*field_, 300000);
  std::cout << source->note() << "\n";
  EXPECT_EQ(source->name(), "pca k=8");
  EXPECT_NE(source->note().find("over the"), std::string::npos) << source->note();
  EXPECT_NE(source->note().find("budget"), std::string::npos) << source->note();
  EXPECT_LE(source->bytes(), 300000u);
  // The same compression on the CPU (noise-floor rank, capped by the budget) relights the same.
  relight::PcaOptions options;
  options.max_rank = 8;
  const relight::PcaField pca = relight::PcaField::build(*field_, options);
  const ViewLighting lighting = environment(90);
  Image cpu;
  pca.relight_led_weights_into(lighting.led_irradiance_rgb.data(), cpu);
  const ImageDifference d = difference(gpu_render(*source, lighting), cpu);
  EXPECT_LT(d.max_relative, 1e-5);  // Measured 0 (same summation order on llvmpipe).
  // Not even rank 1 fits: a HardwareError that says how much was needed.
  try {
    upload_field(*field_, 1000);
    ADD_FAILURE() << "a 1 kB budget was accepted";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("over the 1.0 kB"), std::string::npos) << e.what();
  }
}

TEST_F(GpuRelight, WrongLightingOrTargetSizeIsAnInputError) {
  const auto source = upload_field(*field_);
  ViewLighting lighting = environment(0);
  lighting.led_irradiance_rgb.resize(3 * 39);
  GpuTarget target(64, 48);
  EXPECT_THROW(source->render(lighting, target), InputError);
  GpuTarget wrong(32, 48);
  EXPECT_THROW(source->render(environment(0), wrong), InputError);
}

TEST_F(GpuRelight, DrawToScreenAppliesExposureAndSrgbAndSplits) {
  // Left half 0.25 (field units), right half from a second target at 0.5; exposure +1 stop.
  GpuTarget a(64, 48), b(64, 48);
  {
    relight::ModelMaps flat = synthetic_maps(64, 48, 1);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) flat.maps.at(x, y, relight::kMapModel) = 0;  // All flagged.
    }
    Image quarter(64, 48, 3, 0.25f), half(64, 48, 3, 0.5f);
    relight::ModelRenderOptions options;
    options.flagged_fallback = &quarter;
    upload_models(flat, options)->render(environment(0), a);
    options.flagged_fallback = &half;
    upload_models(flat, options)->render(environment(0), b);
  }
  DisplayOptions display;
  display.exposure_stops = 1.0;
  display.split = &b;
  display.divider = 0.5;
  GpuTarget screen(64, 48);
  GLint previous = 0;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, screen.framebuffer());
  draw_to_screen(a, display, 0, 0, 64, 48);
  display.difference = true;
  const Image split = screen.read_back();
  draw_to_screen(a, display, 0, 0, 64, 48);
  const Image diff = screen.read_back();
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(previous));
  // 0.25 * 2 = 0.5 -> sRGB 0.7354; 0.5 * 2 = 1 -> 1; |0.25 - 0.5| * 2 = 0.5 -> 0.7354.
  EXPECT_NEAR(split.at(10, 20, 0), 0.7354, 1e-3);
  EXPECT_NEAR(split.at(50, 20, 0), 1.0, 1e-3);
  EXPECT_NEAR(split.at(32, 20, 0), 0.9, 1e-3);  // The divider line.
  EXPECT_NEAR(diff.at(10, 20, 0), 0.7354, 1e-3);
  EXPECT_NEAR(diff.at(50, 20, 0), 0.7354, 1e-3);
}

// Without a display GLFW cannot start: a HardwareError that says what to do. (Its own suite: the
// fixture's window would keep GLFW initialised.)
TEST(GlWindow, WithoutADisplayThrowsAHardwareErrorThatSaysWhatToDo) {
  const char* display = std::getenv("DISPLAY");
  const std::optional<std::string> saved =
      display ? std::optional<std::string>(display) : std::nullopt;
  unsetenv("DISPLAY");
  try {
    GlWindow window(32, 32, "no display", false);
    ADD_FAILURE() << "a window opened without DISPLAY";
  } catch (const HardwareError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("no display"), std::string::npos) << message;
    EXPECT_NE(message.find("xvfb-run"), std::string::npos) << message;
  }
  if (saved) setenv("DISPLAY", saved->c_str(), 1);
  // And with the display back, a window opens.
  if (saved) {
    GlWindow window(32, 32, "display back", false);
    EXPECT_FALSE(window.renderer().empty());
  }
}

}  // namespace
}  // namespace ls::viewer
