// The viewer's parameter maps as colours (viewer/viewer_maps.cc): the albedo map is the albedo in
// sRGB, as lightstage/image.h encodes it, and a NaN or out-of-range albedo shows black or white,
// never NaN.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "lightstage/image.h"
#include "relight/fit/fit.h"
#include "viewer/viewer_app_impl.h"

namespace ls::viewer {
namespace {

TEST(ViewerMaps, AlbedoMapIsTheSrgbAlbedoAndNeverNan) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float albedos[][3] = {{0.18f, 0.5f, 0.002f}, {nan, 0.3f, nan}, {2.0f, -0.5f, 1.0f}};
  relight::ModelMaps maps;
  maps.maps = Image(3, 1, relight::kMapChannelCount);
  for (int x = 0; x < 3; ++x) {
    for (int c = 0; c < 3; ++c) maps.maps.at(x, 0, relight::kMapAlbedoR + c) = albedos[x][c];
  }
  app_detail::Legend legend;
  const Image colours = app_detail::parameter_image(maps, ParameterMap::kAlbedo, &legend);
  ASSERT_EQ(colours.channels, 3);
  for (int x = 0; x < 3; ++x) {
    for (int c = 0; c < 3; ++c) {
      const float shown = colours.at(x, 0, c);
      ASSERT_TRUE(std::isfinite(shown)) << "pixel " << x << " channel " << c;
      EXPECT_EQ(shown, srgb_encode(albedos[x][c])) << "pixel " << x << " channel " << c;
    }
  }
  EXPECT_EQ(colours.at(1, 0, 0), 0.0f);                 // NaN: black.
  EXPECT_EQ(colours.at(2, 0, 0), colours.at(2, 0, 2));  // Above 1: white, as 1 is.
  EXPECT_FLOAT_EQ(colours.at(2, 0, 0), 1.0f);
  EXPECT_EQ(colours.at(2, 0, 1), 0.0f);  // Below 0: black.
}

}  // namespace
}  // namespace ls::viewer
