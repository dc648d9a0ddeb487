#include "physics/envmap.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>
#include <utility>
#include <vector>

#include "lightstage/errors.h"
#include "physics/sphere.h"

namespace ls::physics {

namespace {

// "nan", "inf", "-inf" or the shortest round-trippable-ish decimal, for error messages.
std::string format_value(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

// Which source channels hold R, G, B: by name when the file named them (OpenImageIO may reorder
// EXR channels), else the first three; a 1-channel map is grey.
std::array<int, 3> rgb_channel_indices(const Image& image) {
  if (image.channels == 1) return {0, 0, 0};
  std::array<int, 3> index = {0, 1, 2};
  if (int(image.channel_names.size()) == image.channels) {
    const char* names[3] = {"R", "G", "B"};
    std::array<int, 3> found = {-1, -1, -1};
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < image.channels; ++c) {
        if (image.channel_names[c] == names[k]) found[k] = c;
      }
    }
    if (found[0] >= 0 && found[1] >= 0 && found[2] >= 0) index = found;
  }
  return index;
}

// Validates and converts to 3 channels. Throws InputError naming `source` and the field.
Image to_validated_rgb(Image image, const std::string& source, bool allow_negative) {
  // More than four channels only where R, G and B are named among them (which three, else?).
  const std::array<int, 3> src = rgb_channel_indices(image);
  const bool named_rgb = int(image.channel_names.size()) == image.channels && image.channels >= 3 &&
                         image.channel_names[size_t(src[0])] == "R" &&
                         image.channel_names[size_t(src[1])] == "G" &&
                         image.channel_names[size_t(src[2])] == "B";
  if (image.channels == 2 || image.channels < 1 || (image.channels > 4 && !named_rgb)) {
    throw InputError(source +
                     ": channels: expected 1, 3 or 4 channels (RGB radiance), or channels named "
                     "R, G and B among more, got " +
                     std::to_string(image.channels));
  }
  if (image.height < 1 || image.width != 2 * image.height) {
    throw InputError(source + ": size: a lat-long map must be twice as wide as it is tall, got " +
                     std::to_string(image.width) + "x" + std::to_string(image.height));
  }
  if (image.pixels.size() != image.num_pixels() * size_t(image.channels)) {
    throw InputError(source + ": pixels: expected " +
                     std::to_string(image.num_pixels() * size_t(image.channels)) +
                     " values for a " + std::to_string(image.width) + "x" +
                     std::to_string(image.height) + "x" + std::to_string(image.channels) +
                     " image, got " + std::to_string(image.pixels.size()));
  }
  const bool already_rgb = image.channels == 3 && src == std::array<int, 3>{0, 1, 2};
  Image rgb;
  if (!already_rgb) rgb = Image(image.width, image.height, 3);
  const char* rgb_names[3] = {"R", "G", "B"};
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = image.at(x, y, src[c]);
        if (!std::isfinite(v) || (v < 0.0f && !allow_negative)) {
          const std::string channel = image.channels == 1 ? std::string("Y") : rgb_names[c];
          throw InputError(source + ": pixel (x=" + std::to_string(x) + ", y=" + std::to_string(y) +
                           ") channel " + channel + ": radiance must be finite and >= 0, got " +
                           format_value(v));
        }
        if (!already_rgb) rgb.at(x, y, c) = v;
      }
    }
  }
  Image out = already_rgb ? std::move(image) : std::move(rgb);
  out.channel_names = {"R", "G", "B"};
  return out;
}

// Removes lossy-compression ringing (see EnvironmentMap::load): per 8x8 block (DWA's DCT block,
// aligned to the image origin) and channel, zeroes the negatives and scales the positives so the
// block's solid-angle-weighted sum is kept. Returns how many values were negative.
// Ringing oscillates about the true radiance: its negative lobes hold a minority of a map's energy
// (11% in the shared DWA-compressed sky.exr, the worst measured). Negatives holding more than half
// of the positive energy (an all -1 map: all of it) are bad data, not compression.
constexpr double kMaxRingingEnergy = 0.5;

long long repair_negative_values(Image& rgb, const std::string& source) {
  constexpr int kBlock = 8;
  const int w = rgb.width, h = rgb.height;
  std::vector<double> row_sr(h);
  for (int y = 0; y < h; ++y) {
    row_sr[y] = std::cos(std::numbers::pi * y / h) -
                std::cos(std::numbers::pi * (y + 1) / h);  // Common 2 pi / W dropped.
  }
  long long repaired = 0;
  double all_positive = 0, all_negative = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = rgb.at(x, y, c);
        (v < 0 ? all_negative : all_positive) += std::abs(v) * row_sr[y];
      }
    }
  }
  if (all_negative > kMaxRingingEnergy * all_positive) {
    char share[32];
    std::snprintf(share, sizeof share, "%.0f%%",
                  all_positive > 0 ? 100 * all_negative / all_positive : 100.0);
    throw InputError(source + ": radiance: negative values hold " + share +
                     " of the map's positive energy; lossy-compression ringing (repaired) holds " +
                     "less than half: not a radiance map");
  }
  for (int by = 0; by < h; by += kBlock) {
    for (int bx = 0; bx < w; bx += kBlock) {
      const int y_end = std::min(by + kBlock, h), x_end = std::min(bx + kBlock, w);
      for (int c = 0; c < 3; ++c) {
        double positive = 0, negative = 0;
        for (int y = by; y < y_end; ++y) {
          for (int x = bx; x < x_end; ++x) {
            const float v = rgb.at(x, y, c);
            (v < 0 ? negative : positive) += std::abs(v) * row_sr[y];
            repaired += v < 0;
          }
        }
        if (negative == 0) continue;
        const float scale = positive > negative ? float((positive - negative) / positive) : 0.0f;
        for (int y = by; y < y_end; ++y) {
          for (int x = bx; x < x_end; ++x) {
            float& v = rgb.at(x, y, c);
            v = v < 0 ? 0.0f : v * scale;
          }
        }
      }
    }
  }
  return repaired;
}

}  // namespace

EnvironmentMap EnvironmentMap::load(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") {
    throw InputError(path.string() + ": an 8-bit " + ext.substr(1) +
                     " image is display-referred (tone-mapped, clipped to white), not radiance: "
                     "lighting needs an HDR map (.exr or .hdr)");
  }
  Image image = read_image(path);
  // A file says what its channels hold: a grey or XYZ map is not the RGB radiance lighting sums.
  const bool names_rgb = std::all_of(
      image.channel_names.begin(), image.channel_names.end(),
      [](const std::string& n) { return n == "R" || n == "G" || n == "B" || n == "A"; });
  if (image.channels == 1 || (image.channels <= 4 && !names_rgb)) {
    std::string names;
    for (const std::string& n : image.channel_names) names += (names.empty() ? "" : ", ") + n;
    const std::string what =
        image.channels == 1 ? ": channels: 1 (" + names + "), a grey map" : ": channels " + names;
    throw InputError(path.string() + what +
                     ": expected RGB radiance (channels R, G, B, and A if any); a map of other "
                     "quantities (grey, XYZ) would be lit as if it were RGB: convert it first");
  }
  return EnvironmentMap(std::move(image), path.string(), /*repair_negatives=*/true);
}

EnvironmentMap::EnvironmentMap(Image radiance_rgb, std::string source)
    : EnvironmentMap(std::move(radiance_rgb), std::move(source), /*repair_negatives=*/false) {}

EnvironmentMap::EnvironmentMap(Image radiance_rgb, std::string source, bool repair_negatives)
    : radiance_(to_validated_rgb(std::move(radiance_rgb), source, repair_negatives)),
      source_(std::move(source)) {
  if (repair_negatives) negative_values_repaired_ = repair_negative_values(radiance_, source_);
}

Eigen::Vector3d EnvironmentMap::direction(double u, double v) {
  const double theta = std::numbers::pi * v;
  const double phi = 2.0 * std::numbers::pi * u - std::numbers::pi;
  const double sin_theta = std::sin(theta);
  return {sin_theta * std::sin(phi), std::cos(theta), -sin_theta * std::cos(phi)};
}

Eigen::Vector2d EnvironmentMap::uv(const Eigen::Vector3d& dir) {
  const Eigen::Vector3d d = dir.normalized();
  const double theta = std::acos(std::clamp(d.y(), -1.0, 1.0));
  // x = sin(theta) sin(phi), -z = sin(theta) cos(phi).
  const double phi = std::atan2(d.x(), -d.z());
  double u = (phi + std::numbers::pi) / (2.0 * std::numbers::pi);
  if (u >= 1.0) u -= 1.0;
  if (u < 0.0) u += 1.0;
  return {u, theta / std::numbers::pi};
}

double EnvironmentMap::pixel_solid_angle_sr(int row) const {
  const double h = height();
  return (2.0 * std::numbers::pi / width()) *
         (std::cos(std::numbers::pi * row / h) - std::cos(std::numbers::pi * (row + 1) / h));
}

Eigen::Vector3d EnvironmentMap::pixel_direction(int x, int y) const {
  return direction((x + 0.5) / width(), (y + 0.5) / height());
}

Eigen::Vector3f EnvironmentMap::radiance_toward(const Eigen::Vector3d& dir,
                                                double rotation_deg) const {
  // The map rotated by +alpha shows, toward `dir`, what the unrotated map shows toward
  // R_y(-alpha) dir (R_y: right-handed rotation about +Y).
  Eigen::Vector3d d = dir;
  if (rotation_deg != 0.0) d = rotation_about_y(-rotation_deg * std::numbers::pi / 180.0) * dir;
  const Eigen::Vector2d uv_map = uv(d);
  const int w = width(), h = height();
  // Pixel centres sit at (x + 0.5) / W: shift by half a pixel, wrap in u, clamp in v.
  const double fx = uv_map.x() * w - 0.5;
  const double fy = std::clamp(uv_map.y() * h - 0.5, 0.0, double(h - 1));
  const double x_floor = std::floor(fx);
  const float tx = float(fx - x_floor);
  int x0 = int(x_floor) % w;
  if (x0 < 0) x0 += w;
  const int x1 = (x0 + 1) % w;
  const int y0 = std::min(int(fy), h - 1);
  const int y1 = std::min(y0 + 1, h - 1);
  const float ty = float(fy - y0);
  Eigen::Vector3f out;
  for (int c = 0; c < 3; ++c) {
    const float top = (1 - tx) * radiance_.at(x0, y0, c) + tx * radiance_.at(x1, y0, c);
    const float bottom = (1 - tx) * radiance_.at(x0, y1, c) + tx * radiance_.at(x1, y1, c);
    out[c] = (1 - ty) * top + ty * bottom;
  }
  return out;
}

Eigen::Vector3d EnvironmentMap::integral() const {
  Eigen::Vector3d total(0, 0, 0);
  for (int y = 0; y < height(); ++y) {
    Eigen::Vector3d row(0, 0, 0);
    for (int x = 0; x < width(); ++x) {
      for (int c = 0; c < 3; ++c) row[c] += radiance_.at(x, y, c);
    }
    total += row * pixel_solid_angle_sr(y);
  }
  return total;
}

Eigen::Vector3d rotate_about_y(const Eigen::Vector3d& d, double rotation_deg) {
  return (rotation_about_y(rotation_deg * std::numbers::pi / 180.0) * d).normalized();
}

std::vector<CoarseTexel> box_filter_environment(const EnvironmentMap& map, int width,
                                                double rotation_deg) {
  if (width < 4 || width % 2 != 0) {
    throw InputError("environment box filter: width: expected an even number >= 4, got " +
                     std::to_string(width));
  }
  const int fw = map.width(), fh = map.height();
  const int cw = width, ch = width / 2;
  const Image& fine = map.radiance();
  // Pass 1, along u: per fine row, the mean over each coarse column.
  std::vector<double> rows(size_t(fh) * cw * 3, 0.0);
  for (int X = 0; X < cw; ++X) {
    const double u0 = double(X) / cw, u1 = double(X + 1) / cw;
    const int x_first = std::max(0, int(std::floor(u0 * fw)));
    const int x_last = std::min(fw - 1, int(std::ceil(u1 * fw)));
    for (int x = x_first; x <= x_last; ++x) {
      const double overlap = std::min(u1, double(x + 1) / fw) - std::max(u0, double(x) / fw);
      if (overlap <= 0) continue;
      const double w = overlap * cw;  // Fraction of the coarse column.
      for (int y = 0; y < fh; ++y) {
        for (int c = 0; c < 3; ++c) rows[(size_t(y) * cw + X) * 3 + c] += w * fine.at(x, y, c);
      }
    }
  }
  // Pass 2, along v with cos(theta) as the measure: exact solid-angle weights.
  std::vector<CoarseTexel> out;
  for (int Y = 0; Y < ch; ++Y) {
    const double c_top = std::cos(std::numbers::pi * Y / ch),
                 c_bottom = std::cos(std::numbers::pi * (Y + 1) / ch);
    const double solid_angle_sr = (2 * std::numbers::pi / cw) * (c_top - c_bottom);
    const int y_first = std::max(0, int(std::floor(double(Y) / ch * fh)));
    const int y_last = std::min(fh - 1, int(std::ceil(double(Y + 1) / ch * fh)));
    for (int X = 0; X < cw; ++X) {
      Eigen::Vector3d mean(0, 0, 0);
      for (int y = y_first; y <= y_last; ++y) {
        const double overlap = std::min(c_top, std::cos(std::numbers::pi * y / fh)) -
                               std::max(c_bottom, std::cos(std::numbers::pi * (y + 1) / fh));
        if (overlap <= 0) continue;
        for (int c = 0; c < 3; ++c) mean[c] += overlap * rows[(size_t(y) * cw + X) * 3 + c];
      }
      mean /= (c_top - c_bottom);
      if (!(mean.maxCoeff() > 0)) continue;
      const Eigen::Vector3d d0 = EnvironmentMap::direction((X + 0.5) / cw, (Y + 0.5) / ch);
      out.push_back({rotate_about_y(d0, rotation_deg), mean * solid_angle_sr, X, Y});
    }
  }
  return out;
}

}  // namespace ls::physics
