#include "lightstage/backend_registry.h"

#include <algorithm>

#include "lightstage/errors.h"
#include "lightstage/session.h"

namespace ls {

void BackendRegistry::add(Backend backend) {
  LS_CHECK(!backend.name.empty() && backend.open, "a back-end needs a name and an open function");
  auto same = [&](const Backend& b) { return b.name == backend.name; };
  auto it = std::find_if(backends_.begin(), backends_.end(), same);
  if (it != backends_.end()) {
    *it = std::move(backend);
  } else {
    backends_.push_back(std::move(backend));
  }
}

bool BackendRegistry::contains(const std::string& name) const {
  return std::any_of(backends_.begin(), backends_.end(),
                     [&](const Backend& b) { return b.name == name; });
}

const Backend& BackendRegistry::find(const std::string& name,
                                     const std::string& stage_source) const {
  for (const Backend& b : backends_) {
    if (b.name == name) return b;
  }
  std::string known;
  for (const Backend& b : backends_) known += (known.empty() ? "\"" : ", \"") + b.name + "\"";
  throw InputError(stage_source + ": camera.backend: expected one of " +
                   (known.empty() ? std::string("(none registered)") : known) + ", got \"" + name +
                   "\"");
}

std::vector<std::string> BackendRegistry::names() const {
  std::vector<std::string> out;
  for (const Backend& b : backends_) out.push_back(b.name);
  return out;
}

BackendRegistry& backend_registry() {
  static BackendRegistry registry;
  return registry;
}

OpenedBackend open_session_backend(const Session& session) {
  const Backend& backend = backend_registry().find(session.info().backend, session.stage().source);
  std::filesystem::path input_file;
  if (!backend.input_file_name.empty() &&
      std::filesystem::exists(session.dir() / backend.input_file_name)) {
    input_file = session.dir() / backend.input_file_name;
  }
  return backend.open({session.stage(), input_file, session.info().seed});
}

}  // namespace ls
