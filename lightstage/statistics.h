#pragma once
// Small order statistics the modules share.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace ls {

// The median of `values` (the upper one of an even count), 0 when there are none.
inline double median(std::vector<double> values) {
  if (values.empty()) return 0;
  const auto mid = values.begin() + std::ptrdiff_t(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace ls
