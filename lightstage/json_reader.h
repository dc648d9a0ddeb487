#pragma once
// Validating reader for the human-written JSON files (stage, scene, edits). Every error names the
// file, the field path and what was expected: "stage.json: camera.bracket[1].exposure_s: expected a
// positive number (seconds), got -0.1". Unknown keys are errors, so typos never pass silently.
// Internal to .cc files (nlohmann-json is heavy: keep it out of public headers).
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <string_view>

namespace ls {

class JsonReader {
 public:
  JsonReader(const nlohmann::json& value, std::string source, std::string path = "")
      : value_(value), source_(std::move(source)), path_(std::move(path)) {}

  // Parses text; syntax errors name the line and column.
  static nlohmann::json parse(std::string_view text, const std::string& source);

  const nlohmann::json& value() const { return value_; }
  const std::string& path() const { return path_; }
  bool has(const std::string& key) const;
  JsonReader operator[](const std::string& key) const;  // Object member (must exist).
  JsonReader operator[](size_t index) const;            // Array element.
  size_t size() const;                                  // Array length (must be an array).

  // Requires an object whose keys are all in `allowed`.
  void expect_object(std::initializer_list<std::string_view> allowed) const;
  void expect_array() const;

  // Checks that every number here (a number, or an array of them) is one a 32-bit float holds:
  // 0 or 1.2e-38 <= |x| <= 3.4e38, since the pipeline computes in floats (1e39 would be Inf,
  // 1e-39 zero). Returns *this: r["intensity"].fits_float().positive().
  const JsonReader& fits_float() const;
  double number() const;
  double number_in(double lo, double hi, std::string_view what = "") const;
  double positive(std::string_view what = "") const;
  int integer_in(int lo, int hi) const;
  bool boolean() const;
  std::string string() const;
  std::string one_of(std::initializer_list<std::string_view> choices) const;
  Eigen::Vector3d vec3() const;
  Eigen::Vector3d unit_vec3() const;  // Normalised; refuses a zero vector.

  // Optional members with defaults.
  double number_or(const std::string& key, double fallback) const;

  [[noreturn]] void fail(const std::string& expected) const;

 private:
  std::string describe() const;  // What was found, for messages.
  const nlohmann::json& value_;
  std::string source_;
  std::string path_;
};

}  // namespace ls
