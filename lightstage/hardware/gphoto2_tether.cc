// The libgphoto2 2.5 calls, all of them: a Tether over a real camera.
#include <gphoto2/gphoto2.h>

#include <cmath>
#include <cstdlib>

#include "lightstage/hardware/tether.h"

namespace ls {

namespace {

// Errors after which the camera is not there any more (unplugged, switched off, asleep).
bool is_gone(int code) {
  return code == GP_ERROR_IO || code == GP_ERROR_IO_USB_FIND || code == GP_ERROR_IO_USB_CLAIM ||
         code == GP_ERROR_IO_READ || code == GP_ERROR_IO_WRITE || code == GP_ERROR_IO_LOCK ||
         code == GP_ERROR_MODEL_NOT_FOUND || code == GP_ERROR_TIMEOUT;
}

struct ListOwner {
  CameraList* list = nullptr;
  ListOwner() { gp_list_new(&list); }
  ~ListOwner() { gp_list_free(list); }
};

// (model, port) of every camera attached.
std::vector<std::pair<std::string, std::string>> detect(GPContext* context) {
  ListOwner cameras;
  std::vector<std::pair<std::string, std::string>> out;
  const int count = gp_camera_autodetect(cameras.list, context);
  for (int i = 0; i < count; ++i) {
    const char* model = nullptr;
    const char* port = nullptr;
    gp_list_get_name(cameras.list, i, &model);
    gp_list_get_value(cameras.list, i, &port);
    out.emplace_back(model ? model : "?", port ? port : "?");
  }
  return out;
}

class Gphoto2Tether final : public Tether {
 public:
  Gphoto2Tether(const std::string& device, const std::string& stage_source)
      : context_(gp_context_new()) {
    const auto cameras = detect(context_);
    if (cameras.empty()) {
      gp_context_unref(context_);
      throw HardwareError(stage_source +
                          ": camera.backend: \"gphoto2\": libgphoto2 detects no camera (is it "
                          "switched on, on USB, in PC/PTP mode, and not held by another program "
                          "such as gvfs-gphoto2-volume-monitor?)");
    }
    const std::pair<std::string, std::string>* chosen = nullptr;
    std::string seen;
    for (const auto& camera : cameras) {
      seen += (seen.empty() ? "" : ", ") + camera.first + " (" + camera.second + ")";
      if (device.empty() || device == camera.first || device == camera.second) {
        if (!chosen) chosen = &camera;
      }
    }
    if (!chosen || (device.empty() && cameras.size() > 1)) {
      gp_context_unref(context_);
      throw HardwareError(stage_source + ": camera.device: " +
                          (device.empty() ? std::string("several cameras are attached")
                                          : "no camera \"" + device + "\"") +
                          "; libgphoto2 sees " + seen + " (name one by model or port)");
    }
    model_ = chosen->first;
    port_ = chosen->second;
    gp_camera_new(&camera_);
    CameraAbilitiesList* abilities_list = nullptr;
    gp_abilities_list_new(&abilities_list);
    gp_abilities_list_load(abilities_list, context_);
    CameraAbilities abilities;
    const int model_index = gp_abilities_list_lookup_model(abilities_list, model_.c_str());
    if (model_index >= 0 &&
        gp_abilities_list_get_abilities(abilities_list, model_index, &abilities) == GP_OK) {
      gp_camera_set_abilities(camera_, abilities);
    }
    gp_abilities_list_free(abilities_list);
    GPPortInfoList* ports = nullptr;
    gp_port_info_list_new(&ports);
    gp_port_info_list_load(ports);
    const int port_index = gp_port_info_list_lookup_path(ports, port_.c_str());
    GPPortInfo info;
    if (port_index >= 0 && gp_port_info_list_get_info(ports, port_index, &info) == GP_OK) {
      gp_camera_set_port_info(camera_, info);
    }
    gp_port_info_list_free(ports);
    const int code = gp_camera_init(camera_, context_);
    if (code < GP_OK) {
      gp_camera_unref(camera_);
      gp_context_unref(context_);
      throw HardwareError(describe() + ": cannot open it: " + gp_result_as_string(code));
    }
  }

  ~Gphoto2Tether() override {
    gp_camera_exit(camera_, context_);
    gp_camera_unref(camera_);
    gp_context_unref(context_);
  }

  std::string describe() const override { return model_ + " (" + port_ + ")"; }

  std::optional<TetherSetting> setting(const std::string& name) override {
    CameraWidget* widget = nullptr;
    if (gp_camera_get_single_config(camera_, name.c_str(), &widget, context_) < GP_OK) {
      return std::nullopt;
    }
    TetherSetting out;
    CameraWidgetType type;
    gp_widget_get_type(widget, &type);
    if (type == GP_WIDGET_RANGE) {
      float value = 0;
      gp_widget_get_value(widget, &value);
      out.value = std::to_string(value);
    } else if (type == GP_WIDGET_TOGGLE || type == GP_WIDGET_DATE) {
      int value = 0;
      gp_widget_get_value(widget, &value);
      out.value = std::to_string(value);
    } else {
      const char* value = nullptr;
      gp_widget_get_value(widget, &value);
      out.value = value ? value : "";
    }
    for (int i = 0; i < gp_widget_count_choices(widget); ++i) {
      const char* choice = nullptr;
      if (gp_widget_get_choice(widget, i, &choice) == GP_OK && choice) {
        out.choices.emplace_back(choice);
      }
    }
    gp_widget_free(widget);
    return out;
  }

  void set_setting(const std::string& name, const std::string& value) override {
    CameraWidget* widget = nullptr;
    check(gp_camera_get_single_config(camera_, name.c_str(), &widget, context_),
          "reading setting " + name);
    CameraWidgetType type;
    gp_widget_get_type(widget, &type);
    int code = GP_OK;
    if (type == GP_WIDGET_RANGE) {
      const float number = std::strtof(value.c_str(), nullptr);
      code = gp_widget_set_value(widget, &number);
    } else if (type == GP_WIDGET_TOGGLE) {
      const int number = std::atoi(value.c_str());
      code = gp_widget_set_value(widget, &number);
    } else {
      code = gp_widget_set_value(widget, value.c_str());
    }
    if (code >= GP_OK) code = gp_camera_set_single_config(camera_, name.c_str(), widget, context_);
    gp_widget_free(widget);
    check(code, "setting " + name + " to \"" + value + "\"");
  }

  void trigger() override { check(gp_camera_trigger_capture(camera_, context_), "triggering"); }

  TetherEvent wait_event(double timeout_s) override {
    CameraEventType type = GP_EVENT_UNKNOWN;
    void* data = nullptr;
    check(gp_camera_wait_for_event(camera_, int(std::lround(timeout_s * 1000)), &type, &data,
                                   context_),
          "waiting for the shot");
    TetherEvent event;
    switch (type) {
      case GP_EVENT_TIMEOUT:
        event.kind = TetherEvent::Kind::kTimeout;
        break;
      case GP_EVENT_FILE_ADDED: {
        const auto* path = static_cast<CameraFilePath*>(data);
        event.kind = TetherEvent::Kind::kFileAdded;
        event.file = {path->folder, path->name};
        break;
      }
      case GP_EVENT_CAPTURE_COMPLETE:
        event.kind = TetherEvent::Kind::kCaptureComplete;
        break;
      default:
        event.kind = TetherEvent::Kind::kOther;
    }
    std::free(data);
    return event;
  }

  std::vector<std::uint8_t> download(const TetherFile& file) override {
    CameraFile* camera_file = nullptr;
    gp_file_new(&camera_file);
    const int code = gp_camera_file_get(camera_, file.folder.c_str(), file.name.c_str(),
                                        GP_FILE_TYPE_NORMAL, camera_file, context_);
    const char* data = nullptr;
    unsigned long size = 0;
    if (code >= GP_OK) gp_file_get_data_and_size(camera_file, &data, &size);
    std::vector<std::uint8_t> bytes(data, data + (data ? size : 0));
    gp_file_free(camera_file);
    check(code, "downloading " + file.folder + "/" + file.name);
    return bytes;
  }

  void remove(const TetherFile& file) override {
    check(gp_camera_file_delete(camera_, file.folder.c_str(), file.name.c_str(), context_),
          "deleting " + file.folder + "/" + file.name + " from the card");
  }

 private:
  void check(int code, const std::string& what) const {
    if (code >= GP_OK) return;
    const std::string message = describe() + ": " + what + ": " + gp_result_as_string(code);
    if (code == GP_ERROR_CAMERA_BUSY) throw TetherBusy(message);
    if (is_gone(code)) {
      throw HardwareError(message + " (the camera is gone: unplugged, switched off or asleep)");
    }
    throw HardwareError(message);
  }

  GPContext* context_ = nullptr;
  ::Camera* camera_ = nullptr;  // libgphoto2's, not ls::Camera.
  std::string model_, port_;
};

}  // namespace

std::unique_ptr<Tether> open_gphoto2_tether(const std::string& device,
                                            const std::string& stage_source) {
  return std::make_unique<Gphoto2Tether>(device, stage_source);
}

std::vector<std::string> list_gphoto2_cameras() {
  GPContext* context = gp_context_new();
  std::vector<std::string> out;
  for (const auto& [model, port] : detect(context)) out.push_back(model + " (" + port + ")");
  gp_context_unref(context);
  return out;
}

}  // namespace ls
