// The Aravis back-end against Aravis' in-process fake camera ("Fake_1"): the real API path, no
// network (ids starting with "Fake_" enable only the Fake interface).
#include "lightstage/hardware/aravis_camera.h"

#include <arv.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/hardware/gpiod_lights.h"
#include "tests/lightstage/hardware/fake_line_driver.h"
#include "tests/support/test_support.h"

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

// camera.sync.trigger "line": the camera is set to start a frame on its input's rising edge, and
// every frame asks the controller for one pulse. (Aravis' in-process fake streams at its trigger
// frequency whatever its trigger does; that frames wait for the pulse is shown over GigE Vision,
// gige_fake_test.cc.)
TEST(AravisFake, LineTriggerSetsTheInputAndEveryFramePulsesTheControllersLineOnce) {
  CameraSpec spec = FakeSpec(1, 8);
  spec.sync.trigger = "line";
  AravisCamera camera(spec);
  camera.set_fake_trigger_frequency(1000);
  EXPECT_EQ(camera.feature("TriggerSelector"), "FrameStart");
  EXPECT_EQ(camera.feature("TriggerMode"), "On");
  EXPECT_EQ(camera.feature("TriggerSource"), "Line0");
  EXPECT_EQ(camera.feature("TriggerActivation"), "RisingEdge");
  try {
    camera.capture({});
    FAIL() << "line-triggered, and no line wired";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("no controller line wired to it (camera.sync.gpio)"),
              std::string::npos)
        << e.what();
  }
  Stage stage = stage_with_directions(fibonacci_dome_directions(1, 0));
  stage.leds[0].gpio_chip = stage.camera.sync.gpio_chip = "gpiochip0";
  stage.leds[0].gpio_line = 4;
  stage.camera.sync.trigger = "line";
  stage.camera.sync.gpio_line = 9;
  testing::FakeGpio gpio;
  GpioLights lights(stage, std::make_unique<testing::FakeLineDriver>(gpio));
  int rising = 0;
  gpio.wire = [&](const std::pair<std::string, int>& line, bool high) {
    rising += line.second == 9 && high;
  };
  wire_trigger(spec, lights, camera);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(camera.capture({}).raw.width, 64);
    EXPECT_EQ(rising, i + 1);
  }
  gpio.wire = nullptr;
  CameraSpec software = FakeSpec(1, 8);
  EXPECT_THROW(AravisCamera(software).set_trigger_line([] {}), HardwareError);
}

// Aravis' fake camera description with SFNC digital I/O added (LineSelector, and LineMode and
// LineSource per line), as a camera with an exposure-active output has. Its registers lie at
// 0x8000, which the fake leaves free.
std::filesystem::path FakeDescriptionWithDigitalIo(const std::filesystem::path& file) {
  arv_enable_interface("Fake");
  ArvCamera* stock = arv_camera_new("Fake_1", nullptr);
  if (stock == nullptr) return {};
  size_t size = 0;
  const char* text = arv_device_get_genicam_xml(arv_camera_get_device(stock), &size);
  std::string xml(text != nullptr ? text : "", text != nullptr ? size : 0);
  g_object_unref(stock);
  auto reg = [](const std::string& name, const std::string& address, bool per_line) {
    return "<IntReg Name=\"" + name + "\" NameSpace=\"Custom\"><Address>" + address + "</Address>" +
           (per_line ? "<pIndex Offset=\"0x4\">LineSelectorRegister</pIndex>" : "") +
           "<Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>"
           "<Sign>Unsigned</Sign><Endianess>BigEndian</Endianess></IntReg>\n";
  };
  auto enumeration = [](const std::string& name, const std::string& first,
                        const std::string& second) {
    return "<Enumeration Name=\"" + name + "\" NameSpace=\"Standard\"><EnumEntry Name=\"" + first +
           "\" NameSpace=\"Standard\"><Value>0</Value></EnumEntry><EnumEntry Name=\"" + second +
           "\" NameSpace=\"Standard\"><Value>1</Value></EnumEntry><pValue>" + name +
           "Register</pValue></Enumeration>\n";
  };
  const std::string io =
      enumeration("LineSelector", "Line0", "Line1") + reg("LineSelectorRegister", "0x8000", false) +
      enumeration("LineMode", "Input", "Output") + reg("LineModeRegister", "0x8010", true) +
      enumeration("LineSource", "Off", "ExposureActive") +
      reg("LineSourceRegister", "0x8020", true);
  const size_t end = xml.rfind("</RegisterDescription>");
  if (end == std::string::npos) return {};
  xml.insert(end, io);
  std::ofstream(file) << xml;
  return file;
}

// camera.sync.exposure_active_output: the named output is set to ExposureActive; a camera without
// GenICam digital I/O (Aravis' stock fake) is refused with the field and the feature named.
TEST(AravisFake, ExposureActiveOutputIsSetOnTheNamedLineOrRefusedWhereTheCameraHasNone) {
  CameraSpec spec = FakeSpec(1, 8);
  spec.sync.exposure_active_output = "Line1";
  try {
    AravisCamera camera(spec);
    FAIL() << "the stock fake has no digital I/O";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "camera.sync.exposure_active_output \"Line1\": the camera has no LineSelector"),
              std::string::npos)
        << e.what();
  }
  ls::testing::TempDir tmp;
  const std::string description = FakeDescriptionWithDigitalIo(tmp / "fake-io.xml").string();
  ASSERT_FALSE(description.empty());
  arv_set_fake_camera_genicam_filename(description.c_str());  // Read when the fake is created.
  std::unique_ptr<AravisCamera> camera;
  try {
    camera = std::make_unique<AravisCamera>(spec);
  } catch (...) {
    arv_set_fake_camera_genicam_filename(nullptr);
    throw;
  }
  arv_set_fake_camera_genicam_filename(nullptr);
  camera->set_fake_trigger_frequency(1000);
  EXPECT_EQ(camera->feature("LineSelector"), "Line1");
  EXPECT_EQ(camera->feature("LineMode"), "Output");
  EXPECT_EQ(camera->feature("LineSource"), "ExposureActive");
  EXPECT_EQ(camera->capture({}).raw.width, 64);
  camera->set_feature("LineSelector", "Line0");
  EXPECT_EQ(camera->feature("LineMode"), "Input");  // Only the named line.
  EXPECT_EQ(camera->feature("LineSource"), "Off");
}

// Frames whose payload arrives empty (a torn transfer marked complete) are counted and passed
// over, not taken for a broken camera: when none comes whole in time it is a timeout that says how
// many came incomplete and how short, and the next whole frame is delivered.
TEST(AravisFake, EmptyPayloadsArePassedOverAndNamedInTheTimeoutThenTheCameraRecovers) {
  CameraSpec spec = FakeSpec(1, 8);
  spec.timeout_s = 0.2;
  AravisCamera camera(spec);
  camera.set_fake_trigger_frequency(1000);
  camera.set_fake_frames_empty(true);
  try {
    camera.capture({});
    FAIL() << "expected CameraTimeout";
  } catch (const CameraTimeout& e) {
    EXPECT_NE(std::string(e.what()).find("came incomplete (the last 0 bytes of 3072)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_GE(camera.incomplete_frames(), 1);
  camera.set_fake_frames_empty(false);
  EXPECT_EQ(camera.capture({}).raw.width, 64);
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
