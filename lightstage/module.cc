#include "lightstage/module.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <vector>

#include "lightstage/errors.h"

namespace ls {

namespace fs = std::filesystem;

namespace {

std::mutex& modules_mutex() {
  static std::mutex m;
  return m;
}

std::map<std::string, void*>& loaded_modules() {
  static std::map<std::string, void*> modules;
  return modules;
}

std::vector<fs::path> module_folders() {
  if (const char* dir = std::getenv("LIGHTSTAGE_MODULE_DIR"); dir != nullptr && *dir != '\0') {
    return {dir};
  }
  std::vector<fs::path> folders;
  std::error_code ec;
  const fs::path program = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) folders.push_back(program.parent_path().parent_path() / "lib" / "lightstage");
  folders.emplace_back(LIGHTSTAGE_BUILD_MODULE_DIR);  // The build tree's (CMake).
  return folders;
}

}  // namespace

void* module_symbol(const std::string& name, const char* symbol) {
  std::lock_guard<std::mutex> lock(modules_mutex());
  void*& handle = loaded_modules()[name];
  if (handle == nullptr) {
    const std::string file = "lib" + name + ".so";
    std::string looked;
    for (const fs::path& folder : module_folders()) {
      const fs::path path = folder / file;
      looked += (looked.empty() ? "" : ", ") + path.string();
      std::error_code ec;
      if (!fs::exists(path, ec)) continue;
      handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (handle == nullptr) {
        const char* why = ::dlerror();
        loaded_modules().erase(name);
        throw InputError("module " + name + ": cannot load " + path.string() + ": " +
                         (why != nullptr ? why : "unknown error"));
      }
      break;
    }
    if (handle == nullptr) {
      loaded_modules().erase(name);
      throw InputError("module " + name + ": not found (looked for " + looked +
                       "; is the build complete? LIGHTSTAGE_MODULE_DIR names another folder)");
    }
  }
  void* address = ::dlsym(handle, symbol);
  if (address == nullptr) {
    throw InputError("module " + name + ": has no " + symbol + " (built from another version?)");
  }
  return address;
}

bool module_loaded(const std::string& name) {
  std::lock_guard<std::mutex> lock(modules_mutex());
  const auto it = loaded_modules().find(name);
  return it != loaded_modules().end() && it->second != nullptr;
}

}  // namespace ls
