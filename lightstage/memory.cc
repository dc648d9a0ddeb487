#include "lightstage/memory.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
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

// What an address-space limit (ulimit -v) leaves this process, if one is set.
std::optional<std::size_t> address_space_left_bytes() {
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return std::nullopt;
  std::ifstream statm("/proc/self/statm");
  std::size_t pages = 0;
  if (!(statm >> pages)) return std::nullopt;
  const std::size_t used = pages * std::size_t(sysconf(_SC_PAGESIZE));
  return limit.rlim_cur > used ? std::size_t(limit.rlim_cur) - used : 0;
}

// The power of 1024 a unit names ("", "b", "k", "kb", "kib", ... "tib", lower case), or -1.
int unit_power(const std::string& unit) {
  if (unit.empty() || unit == "b") return 0;
  static const std::string kPrefixes = "kmgt";
  const std::size_t prefix = kPrefixes.find(unit[0]);
  if (prefix == std::string::npos) return -1;
  const std::string rest = unit.substr(1);
  return rest.empty() || rest == "b" || rest == "ib" ? int(prefix) + 1 : -1;
}

}  // namespace

std::string format_bytes(std::size_t bytes) {
  static const char* const kUnits[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  if (bytes < 1024) return std::to_string(bytes) + " bytes";
  double value = double(bytes) / 1024;
  int unit = 0;
  while (value >= 1024 && unit < 5) value /= 1024, ++unit;
  char text[32];
  std::snprintf(text, sizeof(text), value == std::floor(value) ? "%.0f %s" : "%.1f %s", value,
                kUnits[unit]);
  return text;
}

MemoryBudget::MemoryBudget(std::size_t bytes) {
  if (bytes > 0) bytes_ = bytes;
}

MemoryBudget MemoryBudget::parse(std::string_view text, std::string_view option) {
  const std::string quoted = std::string(option) + " '" + std::string(text) + "'";
  const std::string sizes =
      "sizes are bytes or a number with K, M, G or T (powers of 1024), "
      "e.g. 512M, 2G, 1.5GiB";
  std::string s(text);
  s.erase(std::remove_if(s.begin(), s.end(), [](unsigned char c) { return std::isspace(c); }),
          s.end());
  if (!s.empty() && s[0] == '-') throw InputError(quoted + ": a size cannot be negative");
  std::size_t digits = 0;
  while (digits < s.size() && (std::isdigit((unsigned char)s[digits]) || s[digits] == '.')) {
    ++digits;
  }
  const std::string number = s.substr(0, digits);
  std::string unit = s.substr(digits);
  for (char& c : unit) c = char(std::tolower((unsigned char)c));
  const int power = unit_power(unit);
  const bool well_formed = !number.empty() && number.front() != '.' && number.back() != '.' &&
                           std::count(number.begin(), number.end(), '.') <= 1;
  if (!well_formed || power < 0) throw InputError(quoted + ": not a size; " + sizes);
  if (power == 0 && number.find('.') != std::string::npos) {
    throw InputError(quoted + ": a number of bytes must be whole; " + sizes);
  }
  // Exact for whole numbers up to 2^64 (long double's 64-bit mantissa), rounded down otherwise.
  const long double value = std::strtold(number.c_str(), nullptr) * std::pow(1024.0L, power);
  if (!(value < std::ldexp(1.0L, 64))) {
    throw InputError(quoted + ": too large (at most 2^64 - 1 bytes)");
  }
  const auto bytes = std::size_t(std::floor(value));
  if (bytes == 0) {
    throw InputError(quoted + ": must be more than 0 (leave " + std::string(option) +
                     " out for the default, half of the memory available)");
  }
  if (bytes < kMinimumBytes) {
    throw InputError(quoted + ": below " + format_bytes(kMinimumBytes) +
                     ", less than any field's row takes; " + sizes);
  }
  return MemoryBudget(bytes);
}

std::size_t MemoryBudget::default_bytes() { return available_memory_bytes() / 2; }

std::size_t MemoryBudget::bytes() const { return bytes_ ? *bytes_ : default_bytes(); }

std::size_t MemoryBudget::bytes_or(std::size_t unset_bytes) const {
  return bytes_ ? *bytes_ : std::min(unset_bytes, default_bytes());
}

std::string MemoryBudget::note(std::string_view option) const {
  if (!bytes_) return {};
  if (const std::size_t available = available_memory_bytes(); *bytes_ > available) {
    return std::string(option) + " " + format_bytes(*bytes_) + " is more than the " +
           format_bytes(available) +
           " of memory available: used as given, so bands as large as that are tried and work "
           "that needs more than is available fails for want of memory";
  }
  if (*bytes_ >= kSmallBytes) return {};
  return std::string(option) + " " + format_bytes(*bytes_) + " is below " +
         format_bytes(kSmallBytes) +
         ": taken as given, the field goes in bands of few rows (slowly), a band holding at "
         "least one row whatever the budget";
}

std::string MemoryBudget::to_string() const {
  return bytes_ ? format_bytes(*bytes_) : "half of the memory available";
}

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
  if (const auto left = address_space_left_bytes()) available = std::min(*available, *left);
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
