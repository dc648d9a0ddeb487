#include "lightstage/memory.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <optional>

#include "lightstage/errors.h"

namespace ls {
namespace {

constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;
// Share of the available memory one allocation may take: the rest is for frames, the OS and others.
constexpr double kMemoryShare = 0.8;

std::string gib(double bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f", bytes / kGiB);
  return text;
}

// A cgroup (v2) memory limit, if we run inside one that is tighter than the machine.
std::optional<std::size_t> cgroup_available_bytes() {
  std::ifstream max_file("/sys/fs/cgroup/memory.max");
  std::ifstream current_file("/sys/fs/cgroup/memory.current");
  std::string max_text;
  std::size_t current = 0;
  if (!(max_file >> max_text) || !(current_file >> current) || max_text == "max") {
    return std::nullopt;
  }
  try {
    const std::size_t limit = std::stoull(max_text);
    return limit > current ? limit - current : 0;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

std::size_t peak_resident_bytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    std::size_t kib = 0;
    if (std::sscanf(line.c_str(), "VmHWM: %zu kB", &kib) == 1) return kib * 1024;
  }
  return 0;
}

std::size_t available_memory_bytes() {
  std::optional<std::size_t> available;
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  std::size_t value_kib = 0;
  std::string unit;
  while (meminfo >> key >> value_kib) {
    std::getline(meminfo, unit);
    if (key == "MemAvailable:") {
      available = value_kib * std::size_t(1024);
      break;
    }
  }
  if (!available) {
    const long pages = sysconf(_SC_AVPHYS_PAGES);
    const long page_size = sysconf(_SC_PAGESIZE);
    available = pages > 0 && page_size > 0 ? std::size_t(pages) * std::size_t(page_size) : 0;
  }
  if (const auto cgroup = cgroup_available_bytes()) available = std::min(*available, *cgroup);
  return *available;
}

void require_memory(std::size_t bytes, const std::string& what, const std::string& advice) {
  const std::size_t available = available_memory_bytes();
  if (double(bytes) > kMemoryShare * double(available)) {
    throw InputError(what + " needs " + gib(double(bytes)) + " GiB but only " +
                     gib(double(available)) + " GiB of memory are available (at most 80% may be " +
                     "used); " + advice);
  }
}

}  // namespace ls
