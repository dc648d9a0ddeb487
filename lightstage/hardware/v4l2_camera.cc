#include "lightstage/hardware/v4l2_camera.h"

#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "lightstage/errors.h"

namespace ls {

struct V4l2Camera::Impl {
  CameraSpec spec;
  cv::VideoCapture cap;
  CameraInfo info;
  double exposure_set = -1, gain_set = -1;
  double exposure_actual_s = 0, gain_actual = 1;
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
  const bool opened = is_index ? impl_->cap.open(std::stoi(dev), cv::CAP_V4L2)
                               : impl_->cap.open(path, cv::CAP_V4L2);
  if (!opened || !impl_->cap.isOpened()) {
    throw HardwareError("V4L2 device " + path +
                        " cannot be opened (busy, no permission: is the user in group video?)");
  }
  impl_->cap.set(cv::CAP_PROP_FRAME_WIDTH, spec.width);
  impl_->cap.set(cv::CAP_PROP_FRAME_HEIGHT, spec.height);
  impl_->cap.set(cv::CAP_PROP_BUFFERSIZE, 1);
  impl_->cap.set(cv::CAP_PROP_AUTO_EXPOSURE, 1);  // V4L2: 1 = manual.
  const int w = int(impl_->cap.get(cv::CAP_PROP_FRAME_WIDTH));
  const int h = int(impl_->cap.get(cv::CAP_PROP_FRAME_HEIGHT));
  if (w != spec.width || h != spec.height) {
    throw HardwareError("V4L2 device " + path + ": camera.width x camera.height " +
                        std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                        " is not offered; the device set " + std::to_string(w) + "x" +
                        std::to_string(h));
  }
  impl_->info = {path, impl_->cap.getBackendName(), w, h, spec.channels, 8};
}

V4l2Camera::~V4l2Camera() = default;

CameraInfo V4l2Camera::info() const { return impl_->info; }

CapturedFrame V4l2Camera::capture(const FrameRequest& request) {
  Impl& m = *impl_;
  if (request.exposure_s != m.exposure_set) {
    // V4L2 exposure_absolute is in units of 100 us.
    m.cap.set(cv::CAP_PROP_EXPOSURE, request.exposure_s * 1e4);
    m.exposure_actual_s = m.cap.get(cv::CAP_PROP_EXPOSURE) * 1e-4;
    m.exposure_set = request.exposure_s;
  }
  if (request.gain != m.gain_set) {
    m.cap.set(cv::CAP_PROP_GAIN, request.gain);
    const double g = m.cap.get(cv::CAP_PROP_GAIN);
    m.gain_actual = g > 0 ? g : 1.0;
    m.gain_set = request.gain;
  }
  cv::Mat img;
  // The driver queues frames exposed before the request: drop one, keep the next.
  if (!m.cap.grab() || !m.cap.grab() || !m.cap.retrieve(img) || img.empty()) {
    throw CameraTimeout("V4L2 device " + m.info.id + ": no frame");
  }
  if (img.cols != m.spec.width || img.rows != m.spec.height) {
    throw HardwareError("V4L2 device " + m.info.id + ": delivered " + std::to_string(img.cols) +
                        "x" + std::to_string(img.rows) + ", expected " +
                        std::to_string(m.spec.width) + "x" + std::to_string(m.spec.height));
  }
  cv::Mat conv;
  cv::cvtColor(img, conv, m.spec.channels == 1 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGR2RGB);
  CapturedFrame frame;
  frame.raw.width = conv.cols;
  frame.raw.height = conv.rows;
  frame.raw.channels = conv.channels();
  frame.raw.bit_depth = 8;
  frame.raw.pixels.resize(size_t(conv.cols) * conv.rows * conv.channels());
  cv::Mat dst(conv.rows, conv.cols, CV_MAKETYPE(CV_16U, conv.channels()), frame.raw.pixels.data());
  conv.convertTo(dst, CV_16U);
  frame.exposure_s = m.exposure_actual_s > 0 ? m.exposure_actual_s : request.exposure_s;
  frame.gain = m.gain_actual;
  return frame;
}

}  // namespace ls
