// PTM and HSH fits and the .ptm / .rti formats.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>

#include "lightstage/errors.h"
#include "relight/compact/rti_fits.h"
#include "relight/compact/rti_io.h"
#include "tests/relight/compact/compact_fixtures.h"

namespace ls::relight {
namespace {

// A field whose every pixel is an exact combination of the basis (plus, per pixel, a colour).
capture::ReflectanceField field_in_basis(RtiBasis basis) {
  const Stage stage = sim::rti_dome_stage(60, 10.0, 6);
  std::vector<capture::FieldLight> lights;
  for (const Led& led : stage.leds) lights.push_back({led.id, led.dir_in_stage, true});
  capture::ReflectanceField field(6, 5, lights);
  const int terms = rti_num_terms(basis);
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 6; ++x) {
      for (int l = 0; l < field.num_lights(); ++l) {
        double t[kMaxRtiTerms];
        rti_basis(basis, lights[l].dir_in_stage, t);
        for (int c = 0; c < 3; ++c) {
          double v = 0;
          for (int j = 0; j < terms; ++j) v += std::sin(1.0 + x + 2 * y + 3 * c + 0.7 * j) * t[j];
          field.at(x, y, l, c) = float(v);
        }
      }
    }
  }
  return field;
}

TEST(RtiFits, RecoverFieldsInTheirOwnBasis) {
  for (RtiBasis basis : {RtiBasis::kPtm, RtiBasis::kHsh2, RtiBasis::kHsh3, RtiBasis::kHsh4}) {
    SCOPED_TRACE(to_string(basis));
    const auto field = field_in_basis(basis);
    RtiFitOptions options;
    options.basis = basis;
    options.ridge = 0;
    const RtiField fit = RtiField::fit(field, options);
    EXPECT_EQ(fit.lights_used, field.num_lights());
    double max_error = 0;
    for (int y = 0; y < 5; ++y) {
      for (int x = 0; x < 6; ++x) {
        for (int c = 0; c < 3; ++c) {
          for (int l = 0; l < field.num_lights(); ++l) {
            max_error = std::max<double>(
                max_error, std::abs(fit.evaluate(x, y, c, field.lights()[l].dir_in_stage) -
                                    field.at(x, y, l, c)));
          }
        }
      }
    }
    EXPECT_LT(max_error, 1e-4);
    // relight_point agrees with evaluate, between LEDs too.
    const Eigen::Vector3d between(0.21, -0.33, 0.92);
    const Image image = fit.relight_point(between);
    EXPECT_NEAR(image.at(4, 3, 1), fit.evaluate(4, 3, 1, between), 1e-5);
    // Behind the image plane nothing lights the RTI bases.
    EXPECT_EQ(fit.relight_point(Eigen::Vector3d(0, 1, -0.2)).pixels,
              std::vector<float>(6 * 5 * 3, 0.0f));
  }
}

TEST(RtiFits, LrgbEqualsRgbWhenColourSeparates) {
  auto field = field_in_basis(RtiBasis::kPtm);
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 6; ++x) {
      for (int l = 0; l < field.num_lights(); ++l) {
        const float g = field.at(x, y, l, 0);
        for (int c = 0; c < 3; ++c) field.at(x, y, l, c) = g * (0.5f + 0.2f * c);
      }
    }
  }
  RtiFitOptions rgb;
  rgb.basis = RtiBasis::kPtm;
  RtiFitOptions lrgb = rgb;
  lrgb.lrgb = true;
  const Eigen::Vector3d light(-0.3, 0.4, 0.86);
  EXPECT_TRUE(testing::ImageNear(RtiField::fit(field, lrgb).relight_point(light),
                                 RtiField::fit(field, rgb).relight_point(light), 1e-4));
}

TEST(RtiFits, RefusesTooFewLightsAndLrgbHsh) {
  auto field = field_in_basis(RtiBasis::kHsh2);
  RtiFitOptions options;
  options.basis = RtiBasis::kHsh3;
  options.lrgb = true;
  EXPECT_THROW(RtiField::fit(field, options), InputError);
  options.lrgb = false;
  options.min_dir_z = 0.99;  // Almost every LED left out.
  EXPECT_THROW(RtiField::fit(field, options), InputError);
}

struct FormatCase {
  RtiBasis basis;
  bool lrgb;
  const char* extension;
  bool srgb = true;  // Display-referred (the default); .rti can also be linear.
};
void PrintTo(const FormatCase& c, std::ostream* os) {
  *os << to_string(c.basis) << (c.lrgb ? " LRGB " : " ") << c.extension
      << (c.srgb ? " sRGB" : " linear");
}

class RtiFormatRoundTrip : public ::testing::TestWithParam<FormatCase> {};

TEST_P(RtiFormatRoundTrip, WriteReadWriteIsBitExactAndValuesWithinQuantisation) {
  const FormatCase p = GetParam();
  const auto& field = compact_testing::sim_field(sim::RtiScene::kGlossy);
  RtiFitOptions options;
  options.basis = p.basis;
  options.lrgb = p.lrgb;
  const float brightest = *std::max_element(field.values().begin(), field.values().end());
  if (p.srgb) options.srgb_gain = 1.0 / brightest;
  const RtiField fit = RtiField::fit(field, options);
  testing::TempDir dir;
  const auto a = dir / (std::string("a") + p.extension);
  const auto b = dir / (std::string("b") + p.extension);
  write_rti_file(a, quantise(fit));
  const RtiFile read = read_rti_file(a);
  write_rti_file(b, read);
  EXPECT_EQ(testing::file_bytes(a), testing::file_bytes(b));
  EXPECT_EQ(read.width, field.width());
  EXPECT_EQ(read.height, field.height());
  EXPECT_EQ(read.srgb, p.srgb);
  // The decoded field relights like the fit, up to 8-bit quantisation of the coefficients:
  // measured relative RMSE (point light, field units) ptm-rgb 0.5%, ptm-lrgb 0.6%, hsh 0.3-1.2%.
  RtiField back = dequantise(read);
  EXPECT_EQ(back.display_gain() > 0, p.srgb);
  const double gain = p.basis == RtiBasis::kPtm ? 1.0 / brightest : 1.0;
  const Eigen::Vector3d light(0.2, 0.3, 0.93);
  Image expected = fit.relight_point(light);
  for (float& v : expected.pixels) v *= float(gain);  // .ptm reads back in display units.
  EXPECT_TRUE(testing::ImageNear(back.relight_point(light), expected, 0.03));
}

INSTANTIATE_TEST_SUITE_P(Formats, RtiFormatRoundTrip,
                         ::testing::Values(FormatCase{RtiBasis::kPtm, false, ".ptm"},
                                           FormatCase{RtiBasis::kPtm, true, ".ptm"},
                                           FormatCase{RtiBasis::kHsh2, false, ".rti"},
                                           FormatCase{RtiBasis::kHsh3, false, ".rti"},
                                           FormatCase{RtiBasis::kHsh4, false, ".rti"},
                                           FormatCase{RtiBasis::kHsh3, false, ".rti", false}),
                         [](const ::testing::TestParamInfo<FormatCase>& info) {
                           return std::string(to_string(info.param.basis)) +
                                  (info.param.lrgb ? "_lrgb" : "") +
                                  (info.param.srgb ? "" : "_linear");
                         });

TEST(RtiIo, PtmHeaderIsTheHpLayout) {
  RtiFitOptions options;
  options.basis = RtiBasis::kPtm;
  options.lrgb = true;
  const std::string bytes =
      encode_rti_file(quantise(RtiField::fit(field_in_basis(RtiBasis::kPtm), options)));
  EXPECT_EQ(bytes.rfind("PTM_1.2\nPTM_FORMAT_LRGB\n6\n5\n", 0), 0u);
  // Six header lines (version, format, width, height, scales, biases), then 6 + 3 bytes per pixel.
  size_t header = 0;
  for (int line = 0; line < 6; ++line) header = bytes.find('\n', header) + 1;
  EXPECT_EQ(bytes.size() - header, 6u * 5 * 9);
}

// Orientation as the viewers read it: .rti rows top to bottom (RTIViewer's Hsh::loadData, relight),
// .ptm rows bottom to top (the HP PTM layout). A file whose top row is known: the first pixel
// bytes after the header are the top row's in .rti and the bottom row's in .ptm.
TEST(RtiIo, RowsAreInTheOrderTheViewersRead) {
  for (const RtiFileFormat format : {RtiFileFormat::kHsh, RtiFileFormat::kPtmRgb}) {
    RtiFile file;
    file.format = format;
    file.width = 3;
    file.height = 4;
    file.terms = format == RtiFileFormat::kHsh ? 4 : 6;
    file.scale.assign(size_t(file.terms), 1.0f);
    file.bias.assign(size_t(file.terms), 0.0f);
    file.data.assign(size_t(file.width) * file.height * file.bytes_per_pixel(), 10);
    const size_t row = size_t(file.width) * file.bytes_per_pixel();
    std::fill_n(file.data.begin(), row, uint8_t(200));  // Row 0: the top row.
    const std::string bytes = encode_rti_file(file);
    if (format == RtiFileFormat::kHsh) {
      const size_t data_start = bytes.size() - file.data.size();
      EXPECT_EQ(uint8_t(bytes[data_start]), 200) << "the top row comes first in .rti";
      EXPECT_EQ(uint8_t(bytes.back()), 10);
    } else {
      // RGB .ptm: three planes, each rows x pixels x 6, bottom row first: the top row ends each.
      const size_t plane = size_t(file.width) * file.height * 6;
      const size_t data_start = bytes.size() - 3 * plane;
      EXPECT_EQ(uint8_t(bytes[data_start]), 10) << "the bottom row comes first in .ptm";
      EXPECT_EQ(uint8_t(bytes[data_start + plane - 1]), 200);
    }
    EXPECT_EQ(decode_rti_file(bytes, "oriented").data, file.data);
  }
}

TEST(RtiIo, MalformedFilesNameFileAndField) {
  testing::TempDir dir;
  RtiFitOptions ptm;
  ptm.basis = RtiBasis::kPtm;
  const std::string good_ptm =
      encode_rti_file(quantise(RtiField::fit(field_in_basis(RtiBasis::kPtm), ptm)));
  RtiFitOptions hsh;
  hsh.basis = RtiBasis::kHsh3;
  const std::string good_hsh =
      encode_rti_file(quantise(RtiField::fit(field_in_basis(RtiBasis::kHsh3), hsh)));
  auto expect_error = [&](const std::string& contents, const std::string& field) {
    const auto path = dir / "bad.file";
    write_file_atomic(path, contents);
    try {
      read_rti_file(path);
      ADD_FAILURE() << "no error for " << field;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    return s.replace(s.find(from), from.size(), to);
  };
  expect_error("GIF89a", "version");
  expect_error(replace(good_ptm, "PTM_1.2", "PTM_9.9"), "version");
  expect_error(replace(good_ptm, "PTM_FORMAT_RGB", "PTM_FORMAT_JPEG_RGB"), "format");
  expect_error(replace(good_ptm, "\n6\n", "\nsix\n"), "width");
  expect_error(good_ptm.substr(0, good_ptm.size() - 1), "data");
  expect_error(good_ptm + "x", "data");
  expect_error(good_ptm.substr(0, 30), "scale");
  expect_error(replace(good_hsh, "\n3\n", "\n1\n"), "type");
  expect_error(replace(good_hsh, "9 2 1", "7 2 1"), "terms");
  expect_error(replace(good_hsh, "9 2 1", "9 9 1"), "basis_type: expected 2 (HSH)");
  expect_error(good_hsh.substr(0, good_hsh.size() - 5), "data");
}

}  // namespace
}  // namespace ls::relight
