#pragma once
// The seam between V4l2Camera (v4l2_camera.cc) and OpenCV's video I/O, which lives in a module
// (lightstage_v4l2, v4l2_module.cc) loaded when a V4L2 camera is opened: videoio brings FFmpeg,
// GStreamer and some 240 libraries into a process, which would pay for them before any work. Only
// standard types cross it, and nothing is thrown across it: a call that fails says so and leaves
// its reason in error(). The module depends on no lightstage library, only on this header.
#include <cstdint>
#include <string>
#include <vector>

namespace ls {

// A frame as the module delivers it: 8-bit, interleaved, rows top first.
struct V4l2Frame {
  int width = 0, height = 0, channels = 0;
  std::vector<std::uint8_t> pixels;
};

class V4l2Video {
 public:
  // What grab() got: a frame, none from the driver (a time-out), or one it cannot convert.
  enum class Grab { kFrame, kNoFrame, kFailed };

  virtual ~V4l2Video() = default;

  // Opens `device` (a path such as "/dev/video0", or an index "0") through V4L2, asks for
  // `width` x `height` (width() and height() say what the device set), one queued buffer and
  // manual exposure. False when it cannot be opened.
  virtual bool open(const std::string& device, int width, int height) = 0;
  virtual int width() const = 0;
  virtual int height() const = 0;
  virtual std::string backend_name() const = 0;  // "V4L2", as OpenCV names it.

  // Requests an exposure time; exposure_s() reads back what the device took (V4L2 counts
  // exposure_absolute in 100 us, converted here), 0 or less when it does not say.
  virtual void set_exposure_s(double exposure_s) = 0;
  virtual double exposure_s() const = 0;
  // Requests an analogue gain (the device's own units); gain() reads it back, 0 or less when the
  // device does not say.
  virtual void set_gain(double gain) = 0;
  virtual double gain() const = 0;

  // Drops the frame the driver queued before the call and delivers the next into `frame`, with
  // `channels` 1 (grey) or 3 (RGB) converted from the device's BGR, at the size it delivered.
  virtual Grab grab(int channels, V4l2Frame& frame) = 0;

  // Why the last call that failed did (empty when it did not say).
  virtual std::string error() const = 0;
};

}  // namespace ls

// The module's one entry point (liblightstage_v4l2.so): a new, unopened device, which the caller
// owns and deletes.
extern "C" ls::V4l2Video* lightstage_v4l2_open();
