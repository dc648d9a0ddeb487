#pragma once
// Checks of option values that CLI11's own do not make.
#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <string>

namespace ls::cli {

// CLI11's numeric checks let NaN through (every comparison with it is false): measurements given
// on the command line must be finite numbers.
inline const CLI::Validator kFinite(
    [](std::string& text) {
      double value = 0;
      const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
      const bool ok =
          error == std::errc() && end == text.data() + text.size() && std::isfinite(value);
      return ok ? std::string() : "expected a finite number, got " + text;
    },
    "FINITE");

// A positive finite number: CLI11's PositiveNumber refuses 0 quoting its range's upper bound,
// the largest double, in 309 digits.
inline const CLI::Validator kPositive(
    [](std::string& text) {
      double value = 0;
      const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
      const bool ok = error == std::errc() && end == text.data() + text.size() &&
                      std::isfinite(value) && value > 0;
      return ok ? std::string() : "expected a positive number, got " + text;
    },
    "POSITIVE");

// A seed is a whole number that fits 64 bits: CLI11 would wrap -1 and clamp larger ones to the
// same 2^64 - 1, so that two different seeds gave one capture.
inline const CLI::Validator kSeed(
    [](std::string& text) {
      unsigned long long value = 0;
      const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
      const bool ok = !text.empty() && error == std::errc() && end == text.data() + text.size();
      return ok ? std::string() : "expected a whole number in 0..18446744073709551615, got " + text;
    },
    "SEED");

}  // namespace ls::cli
