// The V4L2 module (liblightstage_v4l2.so): a V4L2 device through OpenCV's VideoCapture, behind
// lightstage/hardware/v4l2_video.h. Loaded when a V4L2 camera is opened; it depends on no
// lightstage library, and what OpenCV throws stays here as error() text.
#include <exception>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <string>

#include "lightstage/hardware/v4l2_video.h"

namespace ls {
namespace {

class CvV4l2Video final : public V4l2Video {
 public:
  bool open(const std::string& device, int width, int height) override {
    error_.clear();
    try {
      const bool is_index = device.find_first_not_of("0123456789") == std::string::npos;
      const bool opened =
          is_index ? cap_.open(std::stoi(device), cv::CAP_V4L2) : cap_.open(device, cv::CAP_V4L2);
      if (!opened || !cap_.isOpened()) return false;
      cap_.set(cv::CAP_PROP_FRAME_WIDTH, width);
      cap_.set(cv::CAP_PROP_FRAME_HEIGHT, height);
      cap_.set(cv::CAP_PROP_BUFFERSIZE, 1);
      cap_.set(cv::CAP_PROP_AUTO_EXPOSURE, 1);  // V4L2: 1 = manual.
      return true;
    } catch (const std::exception& e) {
      error_ = e.what();
      return false;
    }
  }
  int width() const override { return int(cap_.get(cv::CAP_PROP_FRAME_WIDTH)); }
  int height() const override { return int(cap_.get(cv::CAP_PROP_FRAME_HEIGHT)); }
  std::string backend_name() const override {
    try {
      return cap_.getBackendName();
    } catch (const std::exception&) {
      return "V4L2";  // It throws on a capture that is not open.
    }
  }

  // V4L2 exposure_absolute is in units of 100 us.
  void set_exposure_s(double exposure_s) override {
    cap_.set(cv::CAP_PROP_EXPOSURE, exposure_s * 1e4);
  }
  double exposure_s() const override { return cap_.get(cv::CAP_PROP_EXPOSURE) * 1e-4; }
  void set_gain(double gain) override { cap_.set(cv::CAP_PROP_GAIN, gain); }
  double gain() const override { return cap_.get(cv::CAP_PROP_GAIN); }

  Grab grab(int channels, V4l2Frame& frame) override {
    error_.clear();
    try {
      // The driver queues frames exposed before the request: drop one, keep the next.
      if (!cap_.grab() || !cap_.grab() || !cap_.retrieve(image_) || image_.empty()) {
        return Grab::kNoFrame;
      }
      if (image_.depth() != CV_8U || image_.channels() != 3) {
        error_ = "delivered " + std::to_string(image_.channels()) + "-channel frames of OpenCV " +
                 "depth " + std::to_string(image_.depth()) + ", not 8-bit BGR";
        return Grab::kFailed;
      }
      frame.width = image_.cols;
      frame.height = image_.rows;
      frame.channels = channels;
      frame.pixels.resize(size_t(image_.cols) * image_.rows * channels);
      cv::Mat dst(image_.rows, image_.cols, CV_8UC(channels), frame.pixels.data());
      cv::cvtColor(image_, dst, channels == 1 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGR2RGB);
      return Grab::kFrame;
    } catch (const std::exception& e) {
      error_ = e.what();
      return Grab::kFailed;
    }
  }

  std::string error() const override { return error_; }

 private:
  cv::VideoCapture cap_;
  cv::Mat image_;  // The last frame as retrieved, reused.
  std::string error_;
};

}  // namespace
}  // namespace ls

extern "C" __attribute__((visibility("default"))) ls::V4l2Video* lightstage_v4l2_open() {
  return new ls::CvV4l2Video();
}
