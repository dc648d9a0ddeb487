#pragma once
// A webcam or other V4L2 device through OpenCV's VideoCapture: a simple third back-end for trying
// the pipeline without a machine-vision camera. 8-bit only; exposure and gain are requested through
// V4L2 controls and read back, but many webcams ignore them (the frame reports what was read back).
// OpenCV stays in a module loaded when a device is opened (v4l2_video.h).
#include <memory>

#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls {

class V4l2Camera : public Camera {
 public:
  // Opens CameraSpec::device_id ("/dev/video0" or "0"); throws HardwareError naming the device
  // when it cannot be opened or does not deliver the spec's size, InputError when the spec asks for
  // something a webcam cannot give (bit_depth other than 8).
  explicit V4l2Camera(const CameraSpec& spec);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  CameraInfo info() const override;
  CapturedFrame capture(const FrameRequest& request) override;  // CameraTimeout on a failed read.

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ls
