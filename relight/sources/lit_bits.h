#pragma once
// Internal to relight_sources: a lit mask (one byte a pixel) packed into 64-bit words, one bit a
// pixel, for the shape's per-LED agreement tests.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "relight/sources/source_render.h"

namespace ls::relight {

inline bool lit_bit(const std::vector<std::uint64_t>& bits, std::size_t p) {
  return (bits[p / 64] >> (p % 64)) & 1;
}

inline std::vector<std::uint64_t> pack_lit_bits(const LitMask& mask) {
  std::vector<std::uint64_t> bits((mask.size() + 63) / 64, 0);
  for (std::size_t p = 0; p < mask.size(); ++p) {
    if (mask[p]) bits[p / 64] |= std::uint64_t(1) << (p % 64);
  }
  return bits;
}

}  // namespace ls::relight
