#include "lightstage/hardware/aravis_camera.h"

#include <arv.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>

#include "lightstage/errors.h"

namespace ls {

// ---- Pure helpers
// ---------------------------------------------------------------------------------

namespace {

const char* const kBayerPatterns[] = {"BayerRG", "BayerGR", "BayerGB", "BayerBG"};

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

}  // namespace

int genicam_format_bit_depth(const std::string& f) {
  std::string rest;
  if (starts_with(f, "Mono")) {
    rest = f.substr(4);
  } else if (starts_with(f, "Bayer") && f.size() > 7) {
    rest = f.substr(7);
  } else {
    return 0;
  }
  for (const char* bits : {"8", "10", "12", "14", "16"}) {
    if (rest == bits) return std::atoi(bits);
  }
  return 0;  // Packed (Mono12p, Mono12Packed) and other layouts are not supported.
}

std::vector<std::string> aravis_pixel_format_candidates(int channels, int bit_depth) {
  const std::string bits = std::to_string(bit_depth);
  if (channels == 1) return {"Mono" + bits};
  if (channels == 3) {
    std::vector<std::string> out;
    for (const char* p : kBayerPatterns) out.push_back(p + bits);
    return out;
  }
  return {};
}

RawFrame decode_genicam_image(const void* data, size_t size, const std::string& pixel_format,
                              int width, int height) {
  const int bits = genicam_format_bit_depth(pixel_format);
  if (bits == 0) throw HardwareError("unsupported pixel format " + pixel_format);
  const size_t bytes_per_px = bits > 8 ? 2 : 1;
  const size_t need = size_t(width) * size_t(height) * bytes_per_px;
  if (data == nullptr || size < need) {
    throw HardwareError("camera buffer holds " + std::to_string(size) + " bytes, a " +
                        std::to_string(width) + "x" + std::to_string(height) + " " + pixel_format +
                        " image needs " + std::to_string(need));
  }
  const int depth = bytes_per_px == 2 ? CV_16U : CV_8U;
  // GenICam and OpenCV name Bayer patterns differently: OpenCV names the 2x2 block starting at the
  // second row and column, so GenICam BayerRG (R at the origin) is OpenCV's BayerBG.
  int code = -1;
  if (starts_with(pixel_format, "BayerRG")) code = cv::COLOR_BayerBG2RGB;
  if (starts_with(pixel_format, "BayerGR")) code = cv::COLOR_BayerGB2RGB;
  if (starts_with(pixel_format, "BayerGB")) code = cv::COLOR_BayerGR2RGB;
  if (starts_with(pixel_format, "BayerBG")) code = cv::COLOR_BayerRG2RGB;
  const cv::Mat src(height, width, CV_MAKETYPE(depth, 1), const_cast<void*>(data));
  cv::Mat img = src;
  if (code >= 0) cv::cvtColor(src, img, code);
  RawFrame out;
  out.width = width;
  out.height = height;
  out.channels = img.channels();
  out.bit_depth = bits;
  out.pixels.resize(size_t(width) * height * out.channels);
  cv::Mat dst(height, width, CV_MAKETYPE(CV_16U, out.channels), out.pixels.data());
  img.convertTo(dst, CV_16U);  // 8-bit values stay 0..255.
  return out;
}

// ---- The camera
// -------------------------------------------------------------------------------------

namespace {

// Throws HardwareError when `error` is set, naming the camera and the step.
void check(GError* error, const std::string& camera, const std::string& what) {
  if (error == nullptr) return;
  std::string msg = "camera " + camera + ": " + what + ": " + error->message;
  g_error_free(error);
  throw HardwareError(msg);
}

}  // namespace

struct AravisCamera::Impl {
  CameraSpec spec;
  std::string id;
  ArvCamera* camera = nullptr;
  ArvStream* stream = nullptr;
  CameraInfo info;
  std::string format;
  bool acquiring = false;
  bool gain_available = false;
  double exposure_us_set = -1, exposure_us_actual = 0;
  double gain_set = -1, gain_actual = 1.0;
  int incomplete = 0;
  std::atomic<bool> control_lost{false};
  bool unreachable = false;  // A command failed during capture: the camera may be gone.
  gulong control_lost_handler = 0;

  ~Impl() {
    // A camera that stopped answering would make each command wait out its timeout.
    if (camera && acquiring && !unreachable) {
      GError* error = nullptr;
      arv_camera_stop_acquisition(camera, &error);
      if (error) g_error_free(error);
    }
    if (stream) g_object_unref(stream);
    if (camera) {
      if (control_lost_handler) {
        g_signal_handler_disconnect(arv_camera_get_device(camera), control_lost_handler);
      }
      g_object_unref(camera);
    }
  }

  static void on_control_lost(ArvDevice*, gpointer self) {
    static_cast<Impl*>(self)->control_lost = true;
  }

  void open() {
    if (starts_with(id, "Fake_")) {
      // Only the in-process fake: opening it never touches a network.
      arv_enable_interface("Fake");
      arv_disable_interface("GigEVision");
      arv_disable_interface("USB3Vision");
    }
    GError* error = nullptr;
    camera = arv_camera_new(id.c_str(), &error);
    if (camera == nullptr) {
      std::string msg = error ? error->message : "not found";
      if (error) g_error_free(error);
      throw HardwareError("camera \"" + id + "\" (camera.device_id) cannot be opened: " + msg +
                          "; `lightstage devices` lists the cameras present");
    }
    control_lost_handler = g_signal_connect(arv_camera_get_device(camera), "control-lost",
                                            G_CALLBACK(&Impl::on_control_lost), this);

    // Pixel format: the first candidate the camera offers.
    guint n = 0;
    const char** formats = arv_camera_dup_available_pixel_formats_as_strings(camera, &n, &error);
    check(error, id, "listing pixel formats");
    std::vector<std::string> available(formats, formats + n);
    g_free(formats);
    for (const auto& c : aravis_pixel_format_candidates(spec.channels, spec.bit_depth)) {
      if (std::find(available.begin(), available.end(), c) != available.end()) {
        format = c;
        break;
      }
    }
    if (format.empty()) {
      std::string list;
      for (const auto& f : available) list += (list.empty() ? "" : ", ") + f;
      throw HardwareError("camera " + id + ": no pixel format for camera.channels " +
                          std::to_string(spec.channels) + " and camera.bit_depth " +
                          std::to_string(spec.bit_depth) + " (1 channel: Mono<bits>, 3: Bayer" +
                          "<pattern><bits>); the camera offers: " + list);
    }
    arv_camera_set_pixel_format_from_string(camera, format.c_str(), &error);
    check(error, id, "setting pixel format " + format);

    gint sensor_w = 0, sensor_h = 0;
    arv_camera_get_sensor_size(camera, &sensor_w, &sensor_h, &error);
    check(error, id, "reading the sensor size");
    if (spec.width > sensor_w || spec.height > sensor_h) {
      throw HardwareError("camera " + id + ": camera.width x camera.height " +
                          std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                          " exceeds the sensor (" + std::to_string(sensor_w) + "x" +
                          std::to_string(sensor_h) + ")");
    }
    // Centred region of interest; at the origin when the camera refuses that offset (offsets
    // often come in increments of 4 to 16 pixels).
    arv_camera_set_region(camera, ((sensor_w - spec.width) / 2) & ~15,
                          ((sensor_h - spec.height) / 2) & ~15, spec.width, spec.height, &error);
    if (error != nullptr) {
      g_clear_error(&error);
      arv_camera_set_region(camera, 0, 0, spec.width, spec.height, &error);
      check(error, id, "setting the region");
    }
    gint x = 0, y = 0, w = 0, h = 0;
    arv_camera_get_region(camera, &x, &y, &w, &h, &error);
    check(error, id, "reading the region");
    if (w != spec.width || h != spec.height) {
      throw HardwareError("camera " + id + ": asked for a " + std::to_string(spec.width) + "x" +
                          std::to_string(spec.height) + " region, the camera set " +
                          std::to_string(w) + "x" + std::to_string(h));
    }

    if (arv_camera_is_exposure_auto_available(camera, nullptr)) {
      arv_camera_set_exposure_time_auto(camera, ARV_AUTO_OFF, &error);
      check(error, id, "switching auto exposure off");
    }
    gain_available = arv_camera_is_gain_available(camera, nullptr);
    if (gain_available && arv_camera_is_gain_auto_available(camera, nullptr)) {
      arv_camera_set_gain_auto(camera, ARV_AUTO_OFF, &error);
      check(error, id, "switching auto gain off");
    }
    arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
    check(error, id, "setting continuous acquisition");
    // FrameStart, rising edge (arv_camera_set_trigger), from software or the input line wired to
    // the controller's trigger output.
    const CameraSync& sync = spec.sync;
    arv_camera_set_trigger(camera, sync.line_triggered() ? sync.input.c_str() : "Software", &error);
    check(error, id,
          sync.line_triggered()
              ? "setting the trigger to input " + sync.input + " (camera.sync.input)"
              : std::string("setting the software trigger"));
    if (!sync.exposure_active_output.empty()) output_exposure_active(sync.exposure_active_output);

    if (arv_camera_is_gv_device(camera)) {
      arv_camera_gv_auto_packet_size(camera, nullptr);
    }
    stream = arv_camera_create_stream(camera, nullptr, nullptr, &error);
    check(error, id, "creating the stream");
    if (ARV_IS_GV_STREAM(stream)) {
      // Without it GigE frames drop at high rates.
      g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
    }
    const guint payload = arv_camera_get_payload(camera, &error);
    check(error, id, "reading the payload size");
    for (int i = 0; i < std::max(2, n_buffers); ++i) {
      arv_stream_push_buffer(stream, arv_buffer_new(payload, nullptr));
    }
    arv_camera_start_acquisition(camera, &error);
    check(error, id, "starting acquisition");
    acquiring = true;

    info.id = id;
    const char* model = arv_camera_get_model_name(camera, nullptr);
    const char* vendor = arv_camera_get_vendor_name(camera, nullptr);
    info.model = std::string(vendor ? vendor : "") + (vendor ? " " : "") + (model ? model : "");
    info.width = spec.width;
    info.height = spec.height;
    info.channels = spec.channels;
    info.bit_depth = genicam_format_bit_depth(format);
  }

  // camera.sync.exposure_active_output: that line drives the LED drivers' enable while the sensor
  // integrates (SFNC digital I/O: LineSelector, LineMode, LineSource).
  void output_exposure_active(const std::string& line) {
    const std::string what = "camera.sync.exposure_active_output \"" + line + "\": ";
    for (const char* feature : {"LineSelector", "LineMode", "LineSource"}) {
      if (!arv_camera_is_feature_available(camera, feature, nullptr)) {
        throw HardwareError("camera " + id + ": " + what + "the camera has no " + feature +
                            " feature (GenICam digital I/O), so it cannot gate the LEDs; leave " +
                            "exposure_active_output out to light each LED around its bracket");
      }
    }
    GError* error = nullptr;
    arv_camera_set_string(camera, "LineSelector", line.c_str(), &error);
    check(error, id, what + "selecting the line");
    const char* mode = arv_camera_get_string(camera, "LineMode", &error);
    check(error, id, what + "reading LineMode");
    if (mode == nullptr || std::string(mode) != "Output") {  // Dedicated outputs: read-only.
      arv_camera_set_string(camera, "LineMode", "Output", &error);
      check(error, id, what + "setting LineMode Output");
    }
    arv_camera_set_string(camera, "LineSource", "ExposureActive", &error);
    check(error, id, what + "setting LineSource ExposureActive");
  }

  void apply(const FrameRequest& r) {
    GError* error = nullptr;
    const double exposure_us = r.exposure_s * 1e6;
    if (exposure_us != exposure_us_set) {
      arv_camera_set_exposure_time(camera, exposure_us, &error);
      check(error, id, "setting exposure " + std::to_string(r.exposure_s) + " s");
      exposure_us_actual = arv_camera_get_exposure_time(camera, &error);
      check(error, id, "reading the exposure back");
      exposure_us_set = exposure_us;
    }
    if (r.gain != gain_set) {
      if (gain_available) {
        arv_camera_set_gain(camera, 20.0 * std::log10(std::max(r.gain, 1e-6)), &error);
        check(error, id, "setting gain " + std::to_string(r.gain));
        const double db = arv_camera_get_gain(camera, &error);
        check(error, id, "reading the gain back");
        gain_actual = std::pow(10.0, db / 20.0);
      } else if (r.gain != 1.0) {
        throw HardwareError("camera " + id + ": has no Gain feature; the bracket asks for gain " +
                            std::to_string(r.gain));
      } else {
        gain_actual = 1.0;
      }
      gain_set = r.gain;
    }
  }

  // After a timeout the trigger may still be pending in the camera, and its late frame would be
  // taken for the next request's: stop, recycle every buffer, start again.
  void restart_acquisition() {
    GError* error = nullptr;
    arv_camera_stop_acquisition(camera, &error);
    if (error) g_error_free(error);
    while (ArvBuffer* stale = arv_stream_try_pop_buffer(stream)) {
      arv_stream_push_buffer(stream, stale);
    }
    error = nullptr;
    arv_camera_start_acquisition(camera, &error);
    check(error, id, "restarting acquisition after a timeout");
  }

  size_t payload_bytes() const {
    return size_t(spec.width) * spec.height * ((genicam_format_bit_depth(format) + 7) / 8);
  }

  void trigger() {
    if (spec.sync.line_triggered()) {
      // The controller's fault, not the camera's: the camera stays reachable.
      trigger_line_failed = true;
      if (!pulse_trigger_line) {
        throw HardwareError("camera " + id + ": camera.sync.trigger \"line\" and no " +
                            "controller line wired to it (camera.sync.gpio)");
      }
      pulse_trigger_line();
      trigger_line_failed = false;
      return;
    }
    GError* error = nullptr;
    arv_camera_software_trigger(camera, &error);
    check(error, id, "software trigger");
  }

  CapturedFrame capture(const FrameRequest& r) {
    if (control_lost) throw HardwareError("camera " + id + ": control connection lost");
    apply(r);
    // Frames left over from an earlier, timed-out trigger belong to no request: recycle them.
    while (ArvBuffer* stale = arv_stream_try_pop_buffer(stream)) {
      arv_stream_push_buffer(stream, stale);
    }
    trigger();
    int partial = 0;  // Frames of this request that came incomplete.
    size_t partial_bytes = 0;
    using clock = std::chrono::steady_clock;
    const auto deadline =
        clock::now() + std::chrono::duration<double>(spec.timeout_s + exposure_us_actual * 1e-6);
    for (;;) {
      const double left_us =
          std::chrono::duration<double, std::micro>(deadline - clock::now()).count();
      ArvBuffer* buffer =
          left_us > 0 ? arv_stream_timeout_pop_buffer(stream, guint64(left_us)) : nullptr;
      if (buffer == nullptr) {
        if (control_lost) throw HardwareError("camera " + id + ": control connection lost");
        restart_acquisition();
        const std::string cause =
            partial > 0 ? "; " + std::to_string(partial) + " came incomplete (the last " +
                              std::to_string(partial_bytes) + " bytes of " +
                              std::to_string(payload_bytes()) + ")"
            : spec.sync.line_triggered() ? ": check the wire from camera.sync.gpio to the "
                                           "camera's input " +
                                               spec.sync.input
                                         : std::string();
        throw CameraTimeout(
            "camera " + id + ": no whole frame within " + std::to_string(spec.timeout_s) +
            " s (camera.timeout_s) after " +
            (spec.sync.line_triggered() ? "pulsing the trigger line" : "a software trigger") +
            cause);
      }
      const bool complete = arv_buffer_get_status(buffer) == ARV_BUFFER_STATUS_SUCCESS;
      const int w = arv_buffer_get_image_width(buffer);
      const int h = arv_buffer_get_image_height(buffer);
      if (complete && (w != spec.width || h != spec.height)) {
        arv_stream_push_buffer(stream, buffer);
        throw HardwareError("camera " + id + ": delivered a " + std::to_string(w) + "x" +
                            std::to_string(h) + " frame, expected " + std::to_string(spec.width) +
                            "x" + std::to_string(spec.height));
      }
      size_t size = 0;
      const void* data = arv_buffer_get_image_data(buffer, &size);
      // Packets lost, or a payload cut short (a torn transfer): that frame is gone. Not asked for
      // again here (a late whole frame would answer two triggers): the timeout says so, and the
      // sequencer's retry starts afresh.
      if (!complete || size < payload_bytes()) {
        ++incomplete;
        ++partial;
        partial_bytes = size;
        arv_stream_push_buffer(stream, buffer);
        continue;
      }
      CapturedFrame frame;
      try {
        frame.raw = decode_genicam_image(data, size, format, w, h);
      } catch (...) {
        arv_stream_push_buffer(stream, buffer);
        throw;
      }
      frame.timing.sensor_ns = arv_buffer_get_timestamp(buffer);
      arv_stream_push_buffer(stream, buffer);
      frame.exposure_s = exposure_us_actual * 1e-6;
      frame.gain = gain_actual;
      return frame;
    }
  }

  int n_buffers = 4;
  std::function<void()> pulse_trigger_line;  // camera.sync.trigger "line"; empty: software.
  bool trigger_line_failed = false;
};

AravisCamera::AravisCamera(const CameraSpec& spec, const AravisOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (spec.device_id.empty()) {
    // arv_camera_new(NULL) would open whatever discovery finds first: refuse.
    throw InputError(
        "camera.device_id: expected the Aravis camera id (see `lightstage devices`), "
        "got none");
  }
  impl_->spec = spec;
  impl_->id = spec.device_id;
  impl_->n_buffers = options.n_buffers;
  impl_->open();
}

AravisCamera::~AravisCamera() = default;

CameraInfo AravisCamera::info() const { return impl_->info; }
CapturedFrame AravisCamera::capture(const FrameRequest& request) {
  try {
    return impl_->capture(request);
  } catch (const CameraTimeout&) {
    throw;
  } catch (const HardwareError&) {
    if (!impl_->trigger_line_failed) impl_->unreachable = true;
    impl_->trigger_line_failed = false;
    throw;
  }
}
std::string AravisCamera::pixel_format() const { return impl_->format; }
int AravisCamera::incomplete_frames() const { return impl_->incomplete; }

void AravisCamera::set_feature(const std::string& name, const std::string& value) {
  GError* error = nullptr;
  arv_camera_set_string(impl_->camera, name.c_str(), value.c_str(), &error);
  check(error, impl_->id, "setting " + name + " to " + value);
}

std::string AravisCamera::feature(const std::string& name) const {
  GError* error = nullptr;
  const char* value = arv_camera_get_string(impl_->camera, name.c_str(), &error);
  check(error, impl_->id, "reading " + name);
  return value ? value : "";
}

void AravisCamera::set_trigger_line(const std::function<void()>& pulse) {
  if (!impl_->spec.sync.line_triggered()) {
    throw HardwareError("camera " + impl_->id + ": set for a software trigger, not a line " +
                        "(camera.sync.trigger)");
  }
  impl_->pulse_trigger_line = pulse;
}

void AravisCamera::execute_command(const std::string& name) {
  GError* error = nullptr;
  arv_camera_execute_command(impl_->camera, name.c_str(), &error);
  check(error, impl_->id, "executing " + name);
}

namespace {

ArvFakeCamera* in_process_fake(ArvCamera* camera, const std::string& id) {
  ArvDevice* device = arv_camera_get_device(camera);
  if (!ARV_IS_FAKE_DEVICE(device))
    throw HardwareError("camera " + id + ": not the Aravis fake camera");
  return arv_fake_device_get_fake_camera(ARV_FAKE_DEVICE(device));
}

}  // namespace

void AravisCamera::set_fake_trigger_frequency(double hz) {
  arv_fake_camera_set_trigger_frequency(in_process_fake(impl_->camera, impl_->id), hz);
}

void AravisCamera::set_fake_frames_empty(bool empty) {
  // The in-process fake sends the bytes its fill pattern reports, which only its own pattern does.
  ArvFakeCameraFillPattern nothing = [](ArvBuffer*, void*, guint32, guint32, ArvPixelFormat) {};
  arv_fake_camera_set_fill_pattern(in_process_fake(impl_->camera, impl_->id),
                                   empty ? nothing : nullptr, nullptr);
}

std::vector<AravisDeviceInfo> discover_aravis_cameras() {
  arv_update_device_list();  // Broadcasts: callers run this only on the user's request.
  std::vector<AravisDeviceInfo> out;
  auto s = [](const char* p) { return std::string(p ? p : ""); };
  for (unsigned i = 0; i < arv_get_n_devices(); ++i) {
    out.push_back({s(arv_get_device_id(i)), s(arv_get_device_vendor(i)), s(arv_get_device_model(i)),
                   s(arv_get_device_serial_nbr(i)), s(arv_get_device_protocol(i)),
                   s(arv_get_device_address(i))});
  }
  return out;
}

}  // namespace ls
