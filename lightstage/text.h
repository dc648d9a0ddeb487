#pragma once
// Numbers printed into the lines the modules report.
#include <cstdio>
#include <string>

namespace ls {

// printf's `pattern` over up to three numbers (its conversions take doubles), at most 255 bytes.
inline std::string format_numbers(const char* pattern, double a, double b = 0, double c = 0) {
  char text[256];
  std::snprintf(text, sizeof text, pattern, a, b, c);
  return text;
}

}  // namespace ls
