// The Aravis back-end against Aravis' in-process fake camera ("Fake_1"): the real API path, no
// network (ids starting with "Fake_" enable only the Fake interface).
#include "lightstage/hardware/aravis_camera.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <thread>

#include "lightstage/errors.h"

namespace ls {
namespace {

CameraSpec FakeSpec(int channels, int bit_depth) {
  CameraSpec spec;
  spec.backend = "aravis";
  spec.device_id = "Fake_1";
  spec.width = 64;
  spec.height = 48;
  spec.channels = channels;
  spec.bit_depth = bit_depth;
  spec.timeout_s = 2.0;
  return spec;
}

TEST(AravisFake, CapturesMono8WithExposureAndGainReadBack) {
  AravisCamera camera(FakeSpec(1, 8));
  camera.set_fake_trigger_frequency(1000);  // Default 25 Hz: 40 ms a trigger.
  EXPECT_EQ(camera.pixel_format(), "Mono8");
  const CameraInfo info = camera.info();
  EXPECT_EQ(info.id, "Fake_1");
  EXPECT_EQ(info.width, 64);
  EXPECT_EQ(info.bit_depth, 8);
  FrameRequest request;
  request.exposure_s = 0.0123;
  request.gain = 2.0;
  const CapturedFrame frame = camera.capture(request);
  EXPECT_EQ(frame.raw.width, 64);
  EXPECT_EQ(frame.raw.height, 48);
  EXPECT_EQ(frame.raw.channels, 1);
  EXPECT_EQ(frame.raw.bit_depth, 8);
  EXPECT_EQ(frame.raw.pixels.size(), 64u * 48u);
  EXPECT_NEAR(frame.exposure_s, 0.0123, 1e-6);  // Read back from the camera.
  // The fake's gain is whole dB: 2x = 6.02 dB is read back as 6 dB.
  EXPECT_NEAR(frame.gain, 2.0, 0.02);
  EXPECT_NE(frame.gain, 2.0);
  for (uint16_t v : frame.raw.pixels) ASSERT_LE(v, 255);
  request.exposure_s = 0.002;
  EXPECT_NEAR(camera.capture(request).exposure_s, 0.002, 1e-6);
}

TEST(AravisFake, CapturesMono16) {
  AravisCamera camera(FakeSpec(1, 16));
  camera.set_fake_trigger_frequency(1000);
  EXPECT_EQ(camera.pixel_format(), "Mono16");
  const CapturedFrame frame = camera.capture({});
  EXPECT_EQ(frame.raw.bit_depth, 16);
  EXPECT_EQ(frame.raw.pixels.size(), 64u * 48u);
}

TEST(AravisFake, BayerIsDemosaicedToRgb) {
  AravisCamera camera(FakeSpec(3, 8));
  camera.set_fake_trigger_frequency(1000);
  EXPECT_EQ(camera.pixel_format().rfind("Bayer", 0), 0u) << camera.pixel_format();
  const CapturedFrame frame = camera.capture({});
  EXPECT_EQ(frame.raw.channels, 3);
  EXPECT_EQ(frame.raw.pixels.size(), 64u * 48u * 3u);
}

TEST(AravisFake, ManyFramesInARowAreFast) {
  AravisCamera camera(FakeSpec(1, 8));
  camera.set_fake_trigger_frequency(1000);
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 20; ++i) {
    FrameRequest r;
    r.exposure_s = 0.001 * (1 + i % 3);
    ASSERT_EQ(camera.capture(r).raw.width, 64);
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(s, 2.0);
}

// The fake delivers frames only on its trigger-poll ticks, which fall on whole multiples of the
// poll period (here 500 ms). Right after a frame, the next tick is 500 ms away, so a 300 ms
// timeout must expire; the capture after it spans the next tick and must succeed.
TEST(AravisFake, NoFrameInTimeIsACameraTimeoutAndTheNextFrameStillComes) {
  CameraSpec spec = FakeSpec(1, 8);
  spec.timeout_s = 0.3;
  AravisCamera camera(spec);
  camera.set_fake_trigger_frequency(2);
  // Let the tick scheduled at the old 25 Hz pass: from then on, ticks fall on the 500 ms grid.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  FrameRequest request;
  request.exposure_s = 0.001;
  bool synced = false;  // Until a frame arrives, ticks may fall anywhere.
  for (int attempt = 0; attempt < 4 && !synced; ++attempt) {
    try {
      synced = camera.capture(request).raw.width == 64;
    } catch (const CameraTimeout&) {
    }
  }
  ASSERT_TRUE(synced);
  const auto start = std::chrono::steady_clock::now();
  try {
    camera.capture(request);
    FAIL() << "expected CameraTimeout";
  } catch (const CameraTimeout& e) {
    EXPECT_NE(std::string(e.what()).find("camera.timeout_s"), std::string::npos) << e.what();
  }
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(waited, 0.3);
  // A timeout restarts acquisition; the next tick delivers without reopening the camera.
  EXPECT_EQ(camera.capture(request).raw.width, 64);
  camera.set_feature("TriggerSource", "Software");
  EXPECT_THROW(camera.set_feature("NoSuchFeature", "1"), HardwareError);
  EXPECT_THROW(camera.execute_command("NoSuchCommand"), HardwareError);
}

TEST(AravisFake, UnavailableFormatOrSizeIsAHardwareErrorSayingWhatIsOffered) {
  try {
    AravisCamera camera(FakeSpec(1, 12));
    FAIL();
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("Mono16"), std::string::npos) << e.what();
  }
  CameraSpec big = FakeSpec(1, 8);
  big.width = 4096;
  EXPECT_THROW(AravisCamera camera(big), HardwareError);
}

TEST(AravisCamera, EmptyDeviceIdIsRefusedWithoutDiscovery) {
  CameraSpec spec = FakeSpec(1, 8);
  spec.device_id.clear();
  EXPECT_THROW(AravisCamera camera(spec), InputError);
}

TEST(GenicamDecode, FormatCandidatesAndDepths) {
  EXPECT_EQ(aravis_pixel_format_candidates(1, 12), std::vector<std::string>{"Mono12"});
  EXPECT_EQ(aravis_pixel_format_candidates(3, 8).size(), 4u);
  EXPECT_EQ(genicam_format_bit_depth("Mono12"), 12);
  EXPECT_EQ(genicam_format_bit_depth("BayerGB16"), 16);
  EXPECT_EQ(genicam_format_bit_depth("Mono12Packed"), 0);
  EXPECT_EQ(genicam_format_bit_depth("RGB8"), 0);
}

TEST(GenicamDecode, Mono12IsUnpackedLittleEndian) {
  const uint16_t px[4] = {0, 1, 2048, 4095};
  const RawFrame f = decode_genicam_image(px, sizeof px, "Mono12", 2, 2);
  EXPECT_EQ(f.bit_depth, 12);
  EXPECT_EQ(f.channels, 1);
  EXPECT_EQ(f.pixels, (std::vector<uint16_t>{0, 1, 2048, 4095}));
}

// A flat colour through each GenICam Bayer pattern comes back as that colour (checks the mapping
// to OpenCV's differently named conversion codes).
TEST(GenicamDecode, EveryBayerPatternDemosaicsToTheRightColour) {
  const uint8_t r = 200, g = 100, b = 30;
  struct Pattern {
    const char* name;
    uint8_t c[4];  // The 2x2 block at the origin, row-major.
  };
  const Pattern patterns[] = {{"BayerRG8", {r, g, g, b}},
                              {"BayerGR8", {g, r, b, g}},
                              {"BayerGB8", {g, b, r, g}},
                              {"BayerBG8", {b, g, g, r}}};
  for (const Pattern& p : patterns) {
    const int w = 8, h = 8;
    std::vector<uint8_t> mosaic(w * h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) mosaic[y * w + x] = p.c[(y % 2) * 2 + x % 2];
    const RawFrame f = decode_genicam_image(mosaic.data(), mosaic.size(), p.name, w, h);
    ASSERT_EQ(f.channels, 3);
    EXPECT_EQ(f.at(4, 4, 0), r) << p.name;
    EXPECT_EQ(f.at(4, 4, 1), g) << p.name;
    EXPECT_EQ(f.at(4, 4, 2), b) << p.name;
  }
}

TEST(GenicamDecode, ShortBufferIsAHardwareError) {
  const uint8_t px[3] = {};
  EXPECT_THROW(decode_genicam_image(px, sizeof px, "Mono8", 2, 2), HardwareError);
}

}  // namespace
}  // namespace ls
