#pragma once
// Sources for software OpenGL. Under llvmpipe the "GPU" is these same cores running an emulated
// shader, and the shader loop over 150 LEDs at 512x512 takes 126-295 ms a frame
// (bench_viewer), while the CPU relighting loop (relight/lighting/relight.h: each pixel's samples
// streamed once against weights in cache, TBB over rows) takes ~11 ms. So on a software renderer
// the viewer relights the field and the PCA with the CPU code and uploads the finished image into
// the target: the same result (it is the reference the GPU sources are tested against),
// interactive. On a hardware GPU the shader sources (gpu_relight.h) are used.
#include <memory>

#include "capture/field.h"
#include "relight/compact/pca_field.h"
#include "viewer/gpu_relight.h"

namespace ls::viewer {

// Whether the current context renders in software (GL_RENDERER names llvmpipe, softpipe or
// swrast). Needs a current context.
bool software_renderer();

// Relights on the CPU (relight::relight_into) and uploads the image. `field` must outlive the
// source (the viewer drops its sources whenever it replaces the field).
std::unique_ptr<GpuSource> relight_field_on_cpu(const capture::ReflectanceField& field);
// Relights on the CPU (PcaField::relight_led_weights_into); holds its own copy of the PCA.
std::unique_ptr<GpuSource> relight_pca_on_cpu(const relight::PcaField& pca);

}  // namespace ls::viewer
