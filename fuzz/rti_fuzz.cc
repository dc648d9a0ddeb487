// .ptm (PTM 1.2, RGB and LRGB) and .rti (HSH) files (relight/compact/rti_io.h): any bytes decoded
// as a file, then turned into a field (dequantise) and evaluated at a pixel, as a viewer of the
// file would.
#include "fuzz/fuzz_support.h"
#include "relight/compact/rti_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ls::fuzz::expect_only_input_errors([&] {
    const ls::relight::RtiFile file =
        ls::relight::decode_rti_file(std::string(ls::fuzz::as_text(data, size)), "fuzz.rti");
    const ls::relight::RtiField field = ls::relight::dequantise(file);
    (void)field.evaluate(field.width() - 1, field.height() - 1, 2,
                         Eigen::Vector3d(0.3, 0.2, 0.9).normalized());
  });
  return 0;
}
