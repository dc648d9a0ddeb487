#include "lightstage/json_reader.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"

namespace ls {

namespace {

// Deeper nesting than any lightstage file holds; much deeper would overflow the stack wherever
// the value is walked recursively (printing it into an error message, destroying it).
constexpr int kMaxNesting = 256;

// The deepest nesting of [ and { outside strings.
int nesting_depth(std::string_view text) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

// Refuses a key given twice in one object, which nlohmann would let the last one win: the path
// of each open object or array is kept to name where (camera.width, leds[3].color).
class DuplicateKeys {
 public:
  explicit DuplicateKeys(const std::string& source) : source_(source) {}

  bool operator()(int /*depth*/, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    switch (event) {
      case Event::object_start:
      case Event::array_start:
        frames_.push_back({event == Event::array_start, {}, {}, 0});
        break;
      case Event::key: {
        Frame& object = frames_.back();
        object.key = parsed.get<std::string>();
        if (!object.keys.insert(object.key).second) {
          throw InputError(source_ + ": " + path() + ": given twice in one object (the second " +
                           "would silently replace the first)");
        }
        break;
      }
      case Event::object_end:
      case Event::array_end:
        frames_.pop_back();
        element_done();
        break;
      case Event::value:
        element_done();
        break;
    }
    return true;
  }

 private:
  struct Frame {
    bool array = false;
    std::set<std::string> keys;
    std::string key;  // The object's member being read.
    int index = 0;    // The array's elements read.
  };
  void element_done() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
  }
  std::string path() const {
    std::string out;
    for (const Frame& f : frames_) {
      if (f.array) {
        out += "[" + std::to_string(f.index) + "]";
      } else {
        out += (out.empty() ? "" : ".") + f.key;
      }
    }
    return out;
  }
  const std::string& source_;
  std::vector<Frame> frames_;
};

}  // namespace

nlohmann::json JsonReader::parse(std::string_view text, const std::string& source) {
  if (nesting_depth(text) > kMaxNesting) {
    throw InputError(source + ": not valid here: arrays and objects nested deeper than " +
                     std::to_string(kMaxNesting) + " levels");
  }
  try {
    return nlohmann::json::parse(text.begin(), text.end(), DuplicateKeys(source),
                                 /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const nlohmann::json::parse_error& e) {
    // Convert the byte offset into line:column for humans.
    size_t line = 1, col = 1;
    for (size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    std::string what = e.what();
    const auto pos = what.find("syntax error");
    throw InputError(source + ":" + std::to_string(line) + ":" + std::to_string(col) +
                     ": not valid JSON: " + (pos == std::string::npos ? what : what.substr(pos)));
  } catch (const nlohmann::json::out_of_range& e) {
    // A number beyond a double (1e400): nlohmann refuses it while parsing.
    throw InputError(source + ": not valid here: a number out of the range of a double (" +
                     e.what() + ")");
  }
}

std::string JsonReader::describe() const {
  std::string dumped = value_.dump();
  if (dumped.size() > 60) dumped = dumped.substr(0, 57) + "...";
  return std::string(value_.type_name()) + " " + dumped;
}

void JsonReader::fail(const std::string& expected) const {
  throw InputError(source_ + ": " + (path_.empty() ? "(top level)" : path_) + ": expected " +
                   expected + ", got " + describe());
}

bool JsonReader::has(const std::string& key) const {
  return value_.is_object() && value_.contains(key);
}

JsonReader JsonReader::operator[](const std::string& key) const {
  if (!value_.is_object()) fail("an object");
  const std::string child = path_.empty() ? key : path_ + "." + key;
  if (!value_.contains(key)) {
    throw InputError(source_ + ": " + child + ": missing (required field)");
  }
  return JsonReader(value_.at(key), source_, child);
}

JsonReader JsonReader::operator[](size_t index) const {
  expect_array();
  if (index >= value_.size()) {
    fail("an array of at least " + std::to_string(index + 1) + " entries");
  }
  return JsonReader(value_.at(index), source_, path_ + "[" + std::to_string(index) + "]");
}

size_t JsonReader::size() const {
  expect_array();
  return value_.size();
}

void JsonReader::expect_object(std::initializer_list<std::string_view> allowed) const {
  if (!value_.is_object()) fail("an object");
  for (const auto& [key, _] : value_.items()) {
    bool known = false;
    for (auto a : allowed) known |= (a == key);
    if (!known) {
      std::ostringstream list;
      bool first = true;
      for (auto a : allowed) {
        list << (first ? "" : ", ") << a;
        first = false;
      }
      throw InputError(source_ + ": " + (path_.empty() ? key : path_ + "." + key) +
                       ": unknown field (expected one of: " + list.str() + ")");
    }
  }
}

void JsonReader::expect_array() const {
  if (!value_.is_array()) fail("an array");
}

const JsonReader& JsonReader::fits_float() const {
  const auto fits = [](const nlohmann::json& v) {
    if (!v.is_number()) return true;  // Its reader says what it expected.
    const double x = std::abs(v.get<double>());
    return x == 0 ||
           (x >= std::numeric_limits<float>::min() && x <= std::numeric_limits<float>::max());
  };
  bool ok = fits(value_);
  if (value_.is_array()) {
    for (const nlohmann::json& v : value_) ok = ok && fits(v);
  }
  if (!ok) {
    fail(
        "numbers a 32-bit float holds (0, or 1.2e-38 to 3.4e38 in size: the pipeline computes in "
        "floats)");
  }
  return *this;
}

double JsonReader::number() const {
  if (!value_.is_number()) fail("a number");
  const double v = value_.get<double>();
  if (!std::isfinite(v)) fail("a finite number");
  return v;
}

double JsonReader::number_in(double lo, double hi, std::string_view what) const {
  const double v = number();
  if (v < lo || v > hi) {
    std::ostringstream s;
    s << "a number in [" << lo << ", " << hi << "]" << (what.empty() ? "" : " ") << what;
    fail(s.str());
  }
  return v;
}

double JsonReader::positive(std::string_view what) const {
  const double v = number();
  if (!(v > 0)) fail("a positive number" + (what.empty() ? "" : " " + std::string(what)));
  return v;
}

int JsonReader::integer_in(int lo, int hi) const {
  if (!value_.is_number_integer())
    fail("an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  const auto v = value_.get<long long>();
  if (v < lo || v > hi) {
    fail("an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return int(v);
}

bool JsonReader::boolean() const {
  if (!value_.is_boolean()) fail("true or false");
  return value_.get<bool>();
}

std::string JsonReader::string() const {
  if (!value_.is_string()) fail("a string");
  return value_.get<std::string>();
}

std::string JsonReader::one_of(std::initializer_list<std::string_view> choices) const {
  std::ostringstream list;
  bool first = true;
  for (auto c : choices) {
    list << (first ? "" : ", ") << '"' << c << '"';
    first = false;
  }
  if (!value_.is_string()) fail("one of " + list.str());
  const std::string v = value_.get<std::string>();
  for (auto c : choices) {
    if (c == v) return v;
  }
  fail("one of " + list.str());
}

Eigen::Vector3d JsonReader::vec3() const {
  if (!value_.is_array() || value_.size() != 3) fail("an array of 3 numbers");
  return {(*this)[0].number(), (*this)[1].number(), (*this)[2].number()};
}

Eigen::Vector3d JsonReader::unit_vec3() const {
  const std::optional<Eigen::Vector3d> unit = unit_vector(vec3());
  if (!unit) fail("a non-zero direction vector");
  return *unit;
}

double JsonReader::number_or(const std::string& key, double fallback) const {
  return has(key) ? (*this)[key].number() : fallback;
}

}  // namespace ls
