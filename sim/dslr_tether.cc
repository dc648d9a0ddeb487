#include "sim/dslr_tether.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <thread>

#include "lightstage/hardware/tethered_camera.h"
#include "lightstage/image_file.h"
#include "sim/dng_file.h"

namespace ls::sim {

namespace {

constexpr const char* kFolder = "/store_00010001/DCIM/100LSDSLR";

// A camera's shutter speeds in third stops, 30 s to 1/8000 s, and its ISOs, by their nominal
// values as cameras list them (and as the simulated one exposes them).
std::vector<std::string> shutter_choices() {
  return {"30",     "25",     "20",     "15",     "13",     "10",     "8",      "6",
          "5",      "4",      "3.2",    "2.5",    "2",      "1.6",    "1.3",    "1",
          "0.8",    "0.6",    "0.5",    "0.4",    "0.3",    "1/4",    "1/5",    "1/6",
          "1/8",    "1/10",   "1/13",   "1/15",   "1/20",   "1/25",   "1/30",   "1/40",
          "1/50",   "1/60",   "1/80",   "1/100",  "1/125",  "1/160",  "1/200",  "1/250",
          "1/320",  "1/400",  "1/500",  "1/640",  "1/800",  "1/1000", "1/1250", "1/1600",
          "1/2000", "1/2500", "1/3200", "1/4000", "1/5000", "1/6400", "1/8000"};
}

std::vector<std::string> iso_choices() {
  return {"Auto", "100",  "125",  "160",   "200",   "250",   "320",   "400",  "500",
          "640",  "800",  "1000", "1250",  "1600",  "2000",  "2500",  "3200", "4000",
          "5000", "6400", "8000", "10000", "12800", "16000", "20000", "25600"};
}

// What the camera's JPEG engine makes of a frame: black removed, white at 1, a 2.2 gamma, 8 bits.
std::vector<std::uint8_t> camera_jpeg(const RawFrame& frame, unsigned black, unsigned white) {
  std::vector<std::uint8_t> codes(frame.pixels.size());
  for (size_t i = 0; i < codes.size(); ++i) {
    const double x = std::clamp((double(frame.pixels[i]) - black) / (white - black), 0.0, 1.0);
    codes[i] = std::uint8_t(std::lround(255.0 * std::pow(x, 1.0 / 2.2)));
  }
  image_file::Spec spec;
  spec.width = frame.width;
  spec.height = frame.height;
  spec.channels = frame.channels;
  spec.format = image_file::Sample::kUInt8;
  spec.set("Compression", "jpeg:95");
  image_file::MemorySink sink;
  std::string error;
  const auto writer = image_file::create("shot.jpg", spec, sink, error);
  if (!writer || !writer->write_rows(0, frame.height, image_file::Sample::kUInt8, codes.data()) ||
      !writer->close()) {
    throw HardwareError("simulated DSLR: its JPEG engine failed: " +
                        (writer ? writer->error() : error));
  }
  return std::move(sink.bytes);
}

}  // namespace

SimulatedDslr::SimulatedDslr(Camera& sensor, int raw_bits, unsigned black_level_dn, int pixel_sites,
                             bool real_time, double shot_overhead_s)
    : sensor_(sensor),
      raw_bits_(raw_bits),
      black_level_dn_(black_level_dn),
      pixel_sites_(pixel_sites),
      real_time_(real_time),
      shot_overhead_s_(shot_overhead_s) {
  settings_["shutterspeed"] = {"1/60", shutter_choices()};
  settings_["iso"] = {"100", iso_choices()};
  settings_["f-number"] = {"f/8", {"f/4", "f/5.6", "f/8", "f/11", "f/16"}};
  settings_["imageformat"] = {"RAW", {"Large Fine JPEG", "RAW", "RAW + Large Fine JPEG"}};
  settings_["capturetarget"] = {"Internal RAM", {"Internal RAM", "Memory card"}};
}

void SimulatedDslr::require_connected() const {
  if (gone_) {
    throw HardwareError(describe() +
                        ": I/O problem (the camera is gone: unplugged, switched off or asleep)");
  }
}

std::optional<TetherSetting> SimulatedDslr::setting(const std::string& name) {
  require_connected();
  const auto it = settings_.find(name);
  if (it == settings_.end()) return std::nullopt;
  return it->second;
}

void SimulatedDslr::set_setting(const std::string& name, const std::string& value) {
  require_connected();
  const auto it = settings_.find(name);
  if (it == settings_.end()) throw HardwareError(describe() + ": no setting " + name);
  const auto& choices = it->second.choices;
  if (std::find(choices.begin(), choices.end(), value) == choices.end()) {
    throw HardwareError(describe() + ": setting " + name + " to \"" + value + "\": Bad parameters");
  }
  it->second.value = value;
}

void SimulatedDslr::trigger() {
  gone_ = gone_ || (disconnect_after_ >= 0 && shots_ >= disconnect_after_);
  require_connected();
  if (busy_triggers_ > 0) {
    --busy_triggers_;
    throw TetherBusy(describe() + ": triggering: Camera is busy");
  }
  ++shots_;
  double exposure_s = 0, iso = 0;
  parse_shutter_seconds(settings_["shutterspeed"].value, exposure_s);
  if (!parse_iso(settings_["iso"].value, iso)) iso = 100;
  FrameRequest request = next_;
  request.exposure_s = exposure_s;
  request.gain = iso / 100.0;
  const CapturedFrame frame = sensor_.capture(request);
  BayerImage bayer = bayer_mosaic(frame.raw, black_level_dn_, (1u << raw_bits_) - 1u, pixel_sites_);
  bayer.exposure_s = exposure_s;
  bayer.iso = int(iso);
  const std::string format = settings_["imageformat"].value;
  char stem[32];
  std::snprintf(stem, sizeof stem, "IMG_%04d", shots_ % 10000);
  std::vector<std::string> names;
  if (format.find("RAW") != std::string::npos) {
    names.push_back(std::string(stem) + ".DNG");
    card_[names.back()] = encode_dng(bayer);
  }
  if (format.find("JPEG") != std::string::npos) {
    names.push_back(std::string(stem) + ".JPG");
    card_[names.back()] = camera_jpeg(frame.raw, black_level_dn_, (1u << raw_bits_) - 1u);
  }
  const Clock::time_point ready =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                         real_time_ ? exposure_s + shot_overhead_s_ : 0.0));
  for (const std::string& name : names) {
    if (shots_ == lost_shot_) break;
    events_.push_back({ready, {TetherEvent::Kind::kFileAdded, {kFolder, name}}});
  }
  events_.push_back({ready, {TetherEvent::Kind::kCaptureComplete, {}}});
}

TetherEvent SimulatedDslr::wait_event(double timeout_s) {
  require_connected();
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(std::max(0.0, timeout_s)));
  if (!events_.empty() && events_.front().ready <= deadline) {
    std::this_thread::sleep_until(events_.front().ready);
    TetherEvent event = events_.front().event;
    events_.pop_front();
    return event;
  }
  // Nothing comes in time: a real camera waits out the timeout (at most a moment here, so a
  // simulated capture does not crawl).
  std::this_thread::sleep_until(std::min(deadline, Clock::now() + std::chrono::milliseconds(10)));
  return {};
}

std::vector<std::uint8_t> SimulatedDslr::download(const TetherFile& file) {
  require_connected();
  const auto it = card_.find(file.name);
  if (it == card_.end()) {
    throw HardwareError(describe() + ": downloading " + file.folder + "/" + file.name +
                        ": File not found");
  }
  return it->second;
}

void SimulatedDslr::remove(const TetherFile& file) {
  require_connected();
  card_.erase(file.name);
}

}  // namespace ls::sim
