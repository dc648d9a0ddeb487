#include "lightstage/hardware/tethered_camera.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <thread>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "lightstage/progress.h"
#include "lightstage/raw_photo.h"

namespace ls {

namespace {

bool parse_number(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return end != text.c_str() && std::isfinite(value);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

bool is_jpeg_name(const std::string& name) {
  const std::string ext = lower(std::filesystem::path(name).extension().string());
  return ext == ".jpg" || ext == ".jpeg";
}

// A camera's JPEG as 8-bit codes (its curve is undone later, as camera.response says: "recover").
RawFrame decode_jpeg(const std::vector<std::uint8_t>& bytes, const std::string& name) {
  char path[] = "/tmp/lightstage-shot-XXXXXX";
  const int fd = ::mkstemp(path);
  if (fd < 0) throw StorageError(name + ": cannot write it to /tmp to decode it");
  const bool written = ::write(fd, bytes.data(), bytes.size()) == ssize_t(bytes.size());
  ::close(fd);
  std::string error;
  const auto reader = written ? image_file::open(path, error) : nullptr;
  RawFrame frame;
  if (reader) {
    const image_file::Spec& spec = reader->spec();
    frame = {spec.width, spec.height, spec.channels, 8, {}};
    std::vector<std::uint8_t> codes(size_t(spec.width) * spec.height * spec.channels);
    if (reader->read_rows(0, spec.height, image_file::Sample::kUInt8, codes.data())) {
      frame.pixels.assign(codes.begin(), codes.end());
    } else {
      error = reader->error();
    }
  }
  ::unlink(path);
  if (frame.pixels.empty())
    throw HardwareError(name + ": not a JPEG the camera could mean: " + error);
  return frame;
}

}  // namespace

bool parse_shutter_seconds(const std::string& text, double& seconds) {
  std::string t = text;
  while (!t.empty() && (t.back() == 's' || t.back() == '"' || t.back() == ' ')) t.pop_back();
  const size_t slash = t.find('/');
  if (slash != std::string::npos) {
    double num = 0, den = 0;
    if (!parse_number(t.substr(0, slash), num) || !parse_number(t.substr(slash + 1), den) ||
        den <= 0) {
      return false;
    }
    seconds = num / den;
  } else if (!parse_number(t, seconds)) {
    return false;
  }
  return seconds > 0;
}

bool parse_iso(const std::string& text, double& iso) {
  std::string t = lower(text);
  if (t.rfind("iso", 0) == 0) t = t.substr(3);
  return parse_number(t, iso) && iso > 0;
}

TetheredCamera::TetheredCamera(const CameraSpec& spec, std::unique_ptr<Tether> tether,
                               const std::string& stage_source)
    : spec_(spec), tether_(std::move(tether)), name_("camera " + tether_->describe()) {
  for (const auto& [widget, value] : spec_.tether.settings) {
    const std::optional<TetherSetting> now = tether_->setting(widget);
    const std::string field = stage_source + ": camera.gphoto2.settings." + widget;
    if (!now) throw HardwareError(field + ": " + name_ + " has no such setting");
    if (!now->choices.empty() &&
        std::find(now->choices.begin(), now->choices.end(), value) == now->choices.end()) {
      std::string choices;
      for (const auto& c : now->choices) choices += (choices.empty() ? "\"" : ", \"") + c + "\"";
      throw HardwareError(field + ": " + name_ + " offers " + choices + ", not \"" + value + "\"");
    }
    if (now->value != value) tether_->set_setting(widget, value);
    const std::optional<TetherSetting> after = tether_->setting(widget);
    accepted_.emplace_back(widget, after ? after->value : value);
  }
  // What else decides the photographs, as the camera has it (the shutter and ISO change per frame
  // and are journaled with each).
  for (const char* widget : {"f-number", "aperture", "imageformat", "capturetarget", "whitebalance",
                             "focusmode", "serialnumber"}) {
    const bool set = std::any_of(accepted_.begin(), accepted_.end(),
                                 [&](const auto& s) { return s.first == widget; });
    if (set) continue;
    if (const std::optional<TetherSetting> s = tether_->setting(widget)) {
      accepted_.emplace_back(widget, s->value);
    }
  }
  const auto require = [&](const std::string& name, const char* field) {
    const std::optional<TetherSetting> s = tether_->setting(name);
    if (!s || s->choices.empty()) {
      throw HardwareError(stage_source + ": camera.gphoto2." + field + ": " + name_ +
                          " has no setting \"" + name +
                          "\" with choices (its exposure is set "
                          "through it; name the camera's own with " +
                          field + ")");
    }
    return Widget{name, s->value, s->choices};
  };
  shutter_ = require(spec_.tether.shutter_setting, "shutter_setting");
  iso_ = require(spec_.tether.iso_setting, "iso_setting");
}

std::vector<std::pair<std::string, std::string>> TetheredCamera::reported_settings() const {
  return accepted_;
}

CameraInfo TetheredCamera::info() const {
  CameraInfo info;
  info.id = tether_->describe();
  info.model = tether_->describe();
  info.width = spec_.width;
  info.height = spec_.height;
  info.channels = spec_.channels;
  info.bit_depth = spec_.bit_depth == 8 ? 8 : 16;  // A JPEG camera's codes, or decoded raw.
  return info;
}

// The widget's choice whose value is nearest `wanted` on a log scale (stops); sets `chosen` to it.
std::string TetheredCamera::choose(const Widget& widget, double wanted,
                                   bool (*parse)(const std::string&, double&),
                                   double& chosen) const {
  std::string best;
  double best_distance = INFINITY;
  for (const std::string& c : widget.choices) {
    double value = 0;
    if (!parse(c, value)) continue;
    const double distance = std::abs(std::log2(value / wanted));
    if (distance < best_distance) {
      best_distance = distance;
      best = c;
      chosen = value;
    }
  }
  if (best.empty()) {
    throw HardwareError(name_ + ": no choice of \"" + widget.name + "\" reads as a number");
  }
  return best;
}

void TetheredCamera::set_if_changed(Widget& widget, const std::string& value) {
  if (widget.value == value) return;
  tether_->set_setting(widget.name, value);
  widget.value = value;
}

void TetheredCamera::trigger_when_ready(double deadline_s) {
  const Clock::time_point start = Clock::now();
  for (;;) {
    try {
      tether_->trigger();
      return;
    } catch (const TetherBusy& e) {
      // Still writing the last shot to its card: wait, within the frame's time.
      if (seconds_since(start) > deadline_s) {
        throw CameraTimeout(name_ + ": busy for " + std::to_string(deadline_s) +
                            " s (camera.timeout_s): " + e.what());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
}

CapturedFrame TetheredCamera::capture(const FrameRequest& request) {
  CapturedFrame out;
  const std::string shutter =
      choose(shutter_, request.exposure_s, parse_shutter_seconds, out.exposure_s);
  double iso = 0;
  const std::string iso_choice = choose(iso_, request.gain * spec_.tether.base_iso, parse_iso, iso);
  out.gain = iso / spec_.tether.base_iso;
  set_if_changed(shutter_, shutter);
  set_if_changed(iso_, iso_choice);
  tether_->prepare(request);
  const double allowed_s = out.exposure_s + spec_.timeout_s;
  trigger_when_ready(allowed_s);

  // Every file the shot adds (RAW+JPEG adds two); then the events drained, or some cameras stall.
  // The one decoded: the raw file, or the JPEG of a camera the stage says gives 8-bit codes.
  const bool jpeg_camera = spec_.bit_depth == 8;
  const auto wanted = [jpeg_camera](const TetherFile& f) {
    return jpeg_camera ? is_jpeg_name(f.name) : is_raw_photo_name(f.name);
  };
  const char* kind = jpeg_camera ? "JPEG" : "raw file";
  const Clock::time_point start = Clock::now();
  std::vector<TetherFile> files;
  bool complete = false;
  while (!complete) {
    const double left = allowed_s - seconds_since(start);
    const bool have_wanted = std::any_of(files.begin(), files.end(), wanted);
    if (left <= 0 && !have_wanted) {
      throw CameraTimeout(name_ + ": no " + kind + " within " + std::to_string(allowed_s) +
                          " s of the shot (its exposure plus camera.timeout_s)" +
                          (files.empty() ? "" : "; it added only " + files.front().name));
    }
    const TetherEvent event = tether_->wait_event(have_wanted ? 0.05 : std::max(0.001, left));
    switch (event.kind) {
      case TetherEvent::Kind::kFileAdded:
        files.push_back(event.file);
        break;
      case TetherEvent::Kind::kCaptureComplete:
        if (!have_wanted && !files.empty()) {
          throw HardwareError(
              name_ + ": the shot wrote only " + files.front().name + ", no " + kind +
              (jpeg_camera ? ": set the camera's image format to JPEG, or camera.bit_depth to 16 "
                             "for its raw files"
                           : ": set the camera's image format to RAW (camera.gphoto2.settings, "
                             "e.g. \"imageformat\": \"RAW\"), or camera.bit_depth to 8 for "
                             "its JPEGs"));
        }
        complete = have_wanted;
        break;
      case TetherEvent::Kind::kTimeout:
        complete = have_wanted;  // Nothing more is coming.
        break;
      case TetherEvent::Kind::kOther:
        break;
    }
  }
  for (const TetherFile& file : files) {
    std::vector<std::uint8_t> bytes = tether_->download(file);
    if (spec_.tether.delete_from_camera) tether_->remove(file);
    if (!out.original_file.empty() || !wanted(file)) continue;
    out.original_name = file.name;
    out.original_file = std::move(bytes);
  }
  const std::string file_name = name_ + ": " + out.original_name;
  try {
    out.raw = jpeg_camera ? decode_jpeg(out.original_file, file_name)
                          : decode_raw_photo(out.original_file, file_name, spec_.tether.raw).frame;
  } catch (const InputError& e) {
    throw HardwareError(e.what());  // A file the camera wrote wrong is the camera's fault.
  }
  if (out.raw.width != spec_.width || out.raw.height != spec_.height ||
      out.raw.channels != spec_.channels) {
    const std::string how =
        jpeg_camera ? "" : std::string(" (") + to_string(spec_.tether.raw.mode) + ")";
    throw HardwareError(file_name + " decodes" + how + " to " + std::to_string(out.raw.width) +
                        "x" + std::to_string(out.raw.height) + "x" +
                        std::to_string(out.raw.channels) + "; set camera.width " +
                        std::to_string(out.raw.width) + ", camera.height " +
                        std::to_string(out.raw.height) + " and camera.channels " +
                        std::to_string(out.raw.channels));
  }
  return out;
}

}  // namespace ls
