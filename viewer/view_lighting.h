#pragma once
// The lighting of a viewer frame (ViewLighting, viewer/gpu_relight.h) from an environment map, and
// the light of the map's bright sources on a field: relighting under the sun. A sun or a small
// lamp relit by LED cells is spread over the cells of the LEDs around it, so its shadows come out
// as two or three offset copies; split off (relight/sources/map_relight.h), it is rendered at its
// true direction, turning with the map, while the rest of the map is relit by the cells.
#include <Eigen/Core>
#include <atomic>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/sources/map_relight.h"
#include "viewer/gpu_relight.h"

namespace ls::viewer {

// What the shown sources need of an environment's lighting.
struct EnvironmentNeeds {
  // The field is shown: split the map's bright sources off for it (ViewLighting::split).
  bool field_sources = false;
  // The whole map per LED (ViewLighting::led_irradiance_rgb) for the sources that cannot add a
  // bright source back (PCA). Without it, a lighting with a split leaves led_irradiance_rgb empty
  // (the field needs only the split's weights: 4 ms a rotation saved at 150 LEDs).
  bool whole_map_led_weights = true;
  // Distant lights for the models (ViewLighting::lights), sampled within the LEDs' coverage when
  // LEDs are known (as `lightstage relight --models` with a field).
  bool model_lights = true;
  bool operator==(const EnvironmentNeeds&) const = default;
};

// The map rotated by rotation_deg about +Y as the viewer's sources take it: `split` when
// needs.field_sources and the map has bright sources; led_irradiance_rgb of the whole map
// (integrate_environment over the LEDs' cells) unless a split makes it unneeded; `lights` when
// needs.model_lights. Without LEDs, only `lights`.
ViewLighting environment_lighting(const physics::EnvironmentMap& map, double rotation_deg,
                                  const std::vector<capture::FieldLight>& leds,
                                  const EnvironmentNeeds& needs);

// Whether the lighting has a bright source a field renders (one inside the dome's coverage).
bool renders_bright_sources(const ViewLighting& lighting);

// The bright sources' light on one field, for the field sources (CPU and GPU), through
// relight::MapRelighter. The field's photometric-stereo normals (0.1-1 s at 256^2-512^2) are found
// the first time a lighting has a source to render, so a map without one costs nothing; per-LED
// shadows and per-triangle flows are cached (a few ms the first time a sun falls between new
// LEDs). A field's shadows are then cast as `lightstage relight` casts them, by the scene's shape
// where it agrees with the LEDs, once it is known: the shape is recovered on a thread of its own
// from the normals and LED images the frames' sources hold (seconds: 6 s at 512^2 with 151
// LEDs), and each new direction of a source has
// the shape's visibility traced on another (about 60 ms at 128^2, 2 s at 512^2), kept while the
// source stays; meanwhile the frames cast them by the LEDs' flows alone, at full rate. A PCA's
// keep the flows.
class BrightSourceLight {
 public:
  // `field` must outlive this.
  explicit BrightSourceLight(const capture::ReflectanceField& field);
  // A PCA's sources, from its reconstruction: normals from the reconstructed field (in bands of
  // rows), each LED's image from the PCA under that LED alone. `pca` must outlive this.
  explicit BrightSourceLight(const relight::PcaField& pca);
  // Stops the shape's recovery (at its next LED) and waits for it.
  ~BrightSourceLight();
  BrightSourceLight(const BrightSourceLight&) = delete;
  BrightSourceLight& operator=(const BrightSourceLight&) = delete;
  // Adds the sources of lighting.split (if any) to `out` (the field's size, 3 channels).
  void add(const ViewLighting& lighting, Image& out);
  // The same into `out` alone: zeros plus the sources. False (out untouched) when there is none.
  bool render(const ViewLighting& lighting, Image& out);
  // What cast the last frame's shadows, for the panel: "the scene's shape (as lightstage relight)"
  // or "the LEDs' flows" and why (the shape being recovered, LED 12 of 151; traced for this
  // direction; a PCA).
  std::string shadows() const;

 private:
  // Takes the recovered shape once its thread is done.
  void take_shape();
  int width_ = 0, height_ = 0;
  std::unique_ptr<relight::MapRelighter> relighter_;
  bool of_field_ = false;  // A PCA keeps the flows: no shape.
  std::future<void> recovering_;
  std::future<void> tracing_;
  std::atomic<bool> stop_{false};
  std::atomic<long> recovered_leds_{0}, recovery_steps_{0};
  bool shape_ = false, by_shape_ = false;
  std::string shape_problem_;  // Why the shape is not used (its recovery failed).
};

}  // namespace ls::viewer
