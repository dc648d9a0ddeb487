#include "app/jobs/contact_sheet.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "lightstage/errors.h"

namespace ls::jobs {

void write_contact_sheet(const std::filesystem::path& out, const std::vector<Preview>& tiles,
                         const std::string& title, int tile_size, int max_columns) {
  if (tiles.empty()) return;
  const int columns = std::min<int>(std::max(1, max_columns), int(tiles.size()));
  const int rows = (int(tiles.size()) + columns - 1) / columns;
  constexpr int kLabel = 22, kTitle = 30, kGap = 4;
  cv::Mat sheet(kTitle + rows * (tile_size + kLabel + kGap), columns * (tile_size + kGap), CV_8UC3,
                cv::Scalar(24, 24, 24));
  cv::putText(sheet, title, {8, 21}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {230, 230, 230}, 1,
              cv::LINE_AA);
  for (size_t i = 0; i < tiles.size(); ++i) {
    cv::Mat img = cv::imread(tiles[i].png.string(), cv::IMREAD_COLOR);
    if (img.empty()) throw InputError(tiles[i].png.string() + ": cannot read preview");
    const double s = double(tile_size) / std::max(img.cols, img.rows);
    cv::resize(img, img, {}, s, s, s < 1 ? cv::INTER_AREA : cv::INTER_NEAREST);
    const int x = int(i % columns) * (tile_size + kGap);
    const int y = kTitle + int(i / columns) * (tile_size + kLabel + kGap);
    img.copyTo(sheet(cv::Rect(x, y, img.cols, img.rows)));
    cv::putText(sheet, tiles[i].label, {x + 4, y + tile_size + 16}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
                {220, 220, 220}, 1, cv::LINE_AA);
  }
  if (!cv::imwrite(out.string(), sheet)) throw InputError(out.string() + ": cannot write");
}

}  // namespace ls::jobs
