#pragma once
// Numbers printed into the lines the modules report; names compared as file formats compare them.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <string>
#include <string_view>

namespace ls {

// printf's `pattern` over up to three numbers (its conversions take doubles), at most 255 bytes.
inline std::string format_numbers(const char* pattern, double a, double b = 0, double c = 0) {
  char text[256];
  std::snprintf(text, sizeof text, pattern, a, b, c);
  return text;
}

// ASCII case-insensitive equality (attribute, channel and key names of image formats).
inline bool equals_ignoring_case(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower((unsigned char)x) == std::tolower((unsigned char)y);
         });
}

}  // namespace ls
