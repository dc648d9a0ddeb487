// Compressed fields (`lightstage compress --format pca`, relight/compact/pca_field.h): any bytes as
// an .lspca file, read as the viewer reads it, then relit under one light at every pixel.
#include "fuzz/fuzz_support.h"
#include "relight/compact/pca_field.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path file =
      ls::fuzz::write_file("field.lspca", ls::fuzz::as_text(data, size));
  ls::fuzz::expect_only_input_errors([&] {
    const ls::relight::PcaField pca = ls::relight::PcaField::read(file);
    ls::Image out;
    pca.relight_into(ls::relight::LightingForModels::directional(
                         Eigen::Vector3d(0.2, 0.5, 0.8).normalized(), Eigen::Vector3d(1, 1, 1)),
                     out);
  });
  return 0;
}
