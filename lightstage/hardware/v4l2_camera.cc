#include "lightstage/hardware/v4l2_camera.h"

#include <filesystem>

#include "lightstage/errors.h"
#include "lightstage/hardware/v4l2_video.h"
#include "lightstage/module.h"

namespace ls {

namespace {

// A new device from the lightstage_v4l2 module (OpenCV's video I/O), loaded on the first call. A
// module that cannot be loaded is a fault of this installation, not of the stage file (whose
// InputErrors open_camera prefixes with its name): a HardwareError naming the device.
std::unique_ptr<V4l2Video> new_video(const std::string& path) {
  using Entry = V4l2Video* (*)();
  Entry entry = nullptr;
  try {
    entry = reinterpret_cast<Entry>(module_symbol("lightstage_v4l2", "lightstage_v4l2_open"));
  } catch (const InputError& e) {
    throw HardwareError("V4L2 device " + path + " cannot be opened: " + e.what());
  }
  return std::unique_ptr<V4l2Video>(entry());
}

}  // namespace

struct V4l2Camera::Impl {
  CameraSpec spec;
  std::unique_ptr<V4l2Video> video;
  CameraInfo info;
  double exposure_set = -1, gain_set = -1;
  double exposure_actual_s = 0, gain_actual = 1;
  V4l2Frame frame;  // Reused from capture to capture.
};

V4l2Camera::V4l2Camera(const CameraSpec& spec) : impl_(std::make_unique<Impl>()) {
  impl_->spec = spec;
  const std::string& dev = spec.device_id;
  if (dev.empty()) {
    throw InputError("camera.device_id: expected a V4L2 device such as /dev/video0, got none");
  }
  if (spec.bit_depth != 8) {
    throw InputError("camera.bit_depth: the v4l2 back-end delivers 8-bit frames, got " +
                     std::to_string(spec.bit_depth));
  }
  if (spec.channels != 1 && spec.channels != 3) {
    throw InputError("camera.channels: expected 1 or 3, got " + std::to_string(spec.channels));
  }
  const bool is_index = dev.find_first_not_of("0123456789") == std::string::npos;
  const std::string path = is_index ? "/dev/video" + dev : dev;
  if (!std::filesystem::exists(path)) {
    throw HardwareError("V4L2 device " + path +
                        " (camera.device_id) does not exist; `lightstage devices` lists the "
                        "video devices present");
  }
  // Only now the module: a stage file's mistakes are reported without loading it.
  impl_->video = new_video(path);
  V4l2Video& video = *impl_->video;
  if (!video.open(dev, spec.width, spec.height)) {
    const std::string why = video.error();
    throw HardwareError("V4L2 device " + path +
                        " cannot be opened (busy, no permission: is the user in group video?)" +
                        (why.empty() ? "" : ": " + why));
  }
  const int w = video.width();
  const int h = video.height();
  if (w != spec.width || h != spec.height) {
    throw HardwareError("V4L2 device " + path + ": camera.width x camera.height " +
                        std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                        " is not offered; the device set " + std::to_string(w) + "x" +
                        std::to_string(h));
  }
  impl_->info = {path, video.backend_name(), w, h, spec.channels, 8};
}

V4l2Camera::~V4l2Camera() = default;

CameraInfo V4l2Camera::info() const { return impl_->info; }

CapturedFrame V4l2Camera::capture(const FrameRequest& request) {
  Impl& m = *impl_;
  if (request.exposure_s != m.exposure_set) {
    m.video->set_exposure_s(request.exposure_s);
    m.exposure_actual_s = m.video->exposure_s();
    m.exposure_set = request.exposure_s;
  }
  if (request.gain != m.gain_set) {
    m.video->set_gain(request.gain);
    const double g = m.video->gain();
    m.gain_actual = g > 0 ? g : 1.0;
    m.gain_set = request.gain;
  }
  switch (m.video->grab(m.spec.channels, m.frame)) {
    case V4l2Video::Grab::kFrame:
      break;
    case V4l2Video::Grab::kNoFrame:
      throw CameraTimeout("V4L2 device " + m.info.id + ": no frame");
    case V4l2Video::Grab::kFailed:
      throw HardwareError("V4L2 device " + m.info.id + ": " + m.video->error());
  }
  const V4l2Frame& in = m.frame;
  if (in.width != m.spec.width || in.height != m.spec.height) {
    throw HardwareError("V4L2 device " + m.info.id + ": delivered " + std::to_string(in.width) +
                        "x" + std::to_string(in.height) + ", expected " +
                        std::to_string(m.spec.width) + "x" + std::to_string(m.spec.height));
  }
  CapturedFrame frame;
  frame.raw.width = in.width;
  frame.raw.height = in.height;
  frame.raw.channels = in.channels;
  frame.raw.bit_depth = 8;
  frame.raw.pixels.assign(in.pixels.begin(), in.pixels.end());  // 8-bit codes as they are.
  frame.exposure_s = m.exposure_actual_s > 0 ? m.exposure_actual_s : request.exposure_s;
  frame.gain = m.gain_actual;
  return frame;
}

}  // namespace ls
