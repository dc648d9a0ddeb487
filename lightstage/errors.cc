#include "lightstage/errors.h"

#include <cstdio>
#include <cstdlib>

namespace ls {

std::string printable(std::string_view bytes, std::size_t max_chars) {
  std::string out;
  for (const unsigned char c : bytes.substr(0, max_chars)) {
    if (c >= 0x20 && c < 0x7f) {
      out += char(c);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    }
  }
  return bytes.size() > max_chars ? out + "..." : out;
}

void check_failed(const char* expr, const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "internal error: check failed: %s at %s:%d: %s\n", expr, file, line,
               what.c_str());
  std::abort();
}

}  // namespace ls
