#include "app/jobs/contact_sheet.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "lightstage/image.h"

namespace ls::jobs {

namespace {

// A preview as read_image gives it (8-bit codes over 255) back to its 8-bit RGB codes: grey
// repeated, alpha dropped.
cv::Mat rgb8_of(const Image& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3);
  const bool grey = image.channels < 3;
  for (int y = 0; y < image.height; ++y) {
    auto* row = rgb.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = image.at(x, y, grey ? 0 : c);
        row[x][c] = uchar(std::lround(255.0f * (v > 0.0f ? std::min(v, 1.0f) : 0.0f)));
      }
    }
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
    cv::Mat img = rgb8_of(read_image(tiles[i].png));  // InputError naming the preview.
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
