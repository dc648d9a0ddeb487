#include "lightstage/errors.h"

#include <cstdio>
#include <cstdlib>

namespace ls {

void check_failed(const char* expr, const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "internal error: check failed: %s at %s:%d: %s\n", expr, file, line,
               what.c_str());
  std::abort();
}

}  // namespace ls
