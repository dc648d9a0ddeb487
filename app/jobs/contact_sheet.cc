#include "app/jobs/contact_sheet.h"

#include <algorithm>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "lightstage/errors.h"
#include "lightstage/image.h"

namespace ls::jobs {

namespace {

// A preview's 8-bit RGB codes, read as they are stored (a 12-megapixel preview read as floats took
// a tenth of a relight): grey repeated, alpha dropped. InputError naming the file.
cv::Mat rgb8_of(const std::filesystem::path& png) {
  ImageCodes image = read_image_codes(png);
  if (image.channels > 4) {
    throw InputError(png.string() + ": not a preview image (" + std::to_string(image.channels) +
                     " channels)");
  }
  const cv::Mat codes(image.height, image.width, CV_8UC(image.channels), image.codes.data());
  if (image.channels == 3) return codes.clone();
  cv::Mat rgb;
  if (image.channels == 4) {
    cv::cvtColor(codes, rgb, cv::COLOR_RGBA2RGB);
  } else {
    cv::Mat grey;
    cv::extractChannel(codes, grey, 0);
    cv::cvtColor(grey, rgb, cv::COLOR_GRAY2RGB);
  }
  return rgb;
}

}  // namespace

void write_contact_sheet(const std::filesystem::path& out, const std::vector<Preview>& tiles,
                         const std::string& title, int tile_size, int max_columns) {
  if (tiles.empty()) return;
  const int columns = std::min<int>(std::max(1, max_columns), int(tiles.size()));
  const int rows = (int(tiles.size()) + columns - 1) / columns;
  constexpr int kLabel = 22, kTitle = 30, kGap = 4;
  // In RGB order (read_image's, write_rgb8's); the greys below read the same either way.
  cv::Mat sheet(kTitle + rows * (tile_size + kLabel + kGap), columns * (tile_size + kGap), CV_8UC3,
                cv::Scalar(24, 24, 24));
  cv::putText(sheet, title, {8, 21}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {230, 230, 230}, 1,
              cv::LINE_AA);
  for (size_t i = 0; i < tiles.size(); ++i) {
    cv::Mat img = rgb8_of(tiles[i].png);
    const double s = double(tile_size) / std::max(img.cols, img.rows);
    cv::resize(img, img, {}, s, s, s < 1 ? cv::INTER_AREA : cv::INTER_NEAREST);
    const int x = int(i % columns) * (tile_size + kGap);
    const int y = kTitle + int(i / columns) * (tile_size + kLabel + kGap);
    img.copyTo(sheet(cv::Rect(x, y, img.cols, img.rows)));
    cv::putText(sheet, tiles[i].label, {x + 4, y + tile_size + 16}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
                {220, 220, 220}, 1, cv::LINE_AA);
  }
  write_rgb8(out, sheet.cols, sheet.rows, sheet.ptr<uint8_t>());  // A new Mat: continuous.
}

}  // namespace ls::jobs
