#include "aosr/scene/telescope.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "aosr/io/image_io.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// The paper's system as the issue states it.
TEST(TelescopePresetTest, PaperSystemLoadsWithItsNumbers) {
  const TelescopePreset p = LoadTelescopePreset("paper-8m");
  EXPECT_DOUBLE_EQ(p.aperture.pupil.diameter_m, 8.0);
  EXPECT_DOUBLE_EQ(p.science_wavelength_m, 2.2e-6);
  EXPECT_NEAR(p.camera_pixel_rad, 2.2e-6 / 8.0, 1e-15);
  ASSERT_TRUE(p.atmosphere && p.ao);
  EXPECT_DOUBLE_EQ(p.atmosphere->r0_m, 0.15);
  EXPECT_DOUBLE_EQ(p.atmosphere->r0_wavelength_m, 550e-9);
  EXPECT_DOUBLE_EQ(p.atmosphere->L0_m, 30.0);
  ASSERT_EQ(p.atmosphere->layers.size(), 3u);
  EXPECT_DOUBLE_EQ(p.atmosphere->layers[2].altitude_m, 10000.0);
  EXPECT_DOUBLE_EQ(p.atmosphere->layers[1].cn2_fraction, 0.25);
  EXPECT_DOUBLE_EQ(p.atmosphere->layers[2].wind_speed_mps, 25.0);
  EXPECT_EQ(p.ao->dm.actuators_across, 17);
  EXPECT_DOUBLE_EQ(p.ao->dm.pitch_m, 0.5);  // Fried geometry: D / (17 - 1)
  EXPECT_EQ(p.ao->wfs.lenslets_across, 16);
  EXPECT_DOUBLE_EQ(p.ao->loop.rate_hz, 800.0);
  EXPECT_DOUBLE_EQ(p.ao->loop.gain, 0.35);
  const AnalyticAoOptions a = p.ToAnalyticAo();
  std::string why;
  EXPECT_TRUE(a.IsValid(&why)) << why;
}

TEST(TelescopePresetTest, BenchPixelScaleFromFocalLength) {
  const TelescopePreset p = LoadTelescopePreset("paper-bench");
  EXPECT_DOUBLE_EQ(p.aperture.pupil.diameter_m, 0.0135);
  EXPECT_NEAR(p.camera_pixel_rad, 70.32e-6 / 0.4, 1e-15);
  EXPECT_FALSE(p.atmosphere.has_value());
  ASSERT_TRUE(p.ao.has_value());
  EXPECT_EQ(p.ao->wfs.lenslets_across, 25);
}

// A pupil mask from an image file replaces the geometric aperture, resampled with its area conserved.
TEST(TelescopePresetTest, MaskFileAndSegments) {
  const std::string dir = ::testing::TempDir();
  Image mask = Image::Zero(64, 64);
  mask.block(8, 8, 48, 48).setOnes();  // a square aperture
  WriteViewImage(dir + "/aosr_mask.tif", mask, [] {
    ViewOptions v;
    v.bits = 32;
    return v;
  }());
  const std::string text = R"({"name": "m", "telescope": {"diameter_m": 2, "pupil_px": 32, "mask_file": ")" + dir +
                           R"(/aosr_mask.tif"}, "science": {"wavelength_m": 1e-6, "camera_pixel_mas": 50}})";
  const TelescopePreset p = ParseTelescopePreset(nlohmann::json::parse(text), "m.json");
  const Image a = p.PupilAmplitude();
  EXPECT_EQ(a.rows(), 32);
  EXPECT_NEAR(a.sum() / (32.0 * 32.0), mask.sum() / (64.0 * 64.0), 1e-6);
  const std::string seg = R"({"name": "k", "telescope": {"diameter_m": 12.7, "segments": {"rings": 3,
      "flat_to_flat_m": 1.8, "gap_m": 0.003}}, "science": {"wavelength_m": 2.2e-6, "camera_pixel_mas": 10}})";
  const TelescopePreset k = ParseTelescopePreset(nlohmann::json::parse(seg), "k.json");
  EXPECT_EQ(k.aperture.outline, ApertureOutline::kHexSegments);
  EXPECT_GT(k.PupilAmplitude().sum(), 0);
  std::remove((dir + "/aosr_mask.tif").c_str());
}

TEST(TelescopePresetTest, ErrorsNameTheFieldAndThePresets) {
  using ::testing::HasSubstr;
  auto err = [](const std::string& text) {
    try {
      ParseTelescopePreset(nlohmann::json::parse(text), "x.json");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string ok_science = R"("science": {"wavelength_m": 2e-6, "camera_pixel_mas": 20})";
  EXPECT_THAT(err(R"({"name": "t", "telescope": {"diameter_m": -8}, )" + ok_science + "}"),
              HasSubstr("x.json: telescope.diameter_m = -8"));
  EXPECT_THAT(err(R"({"name": "t", "telescope": {"diameter_m": 8, "obstructon": 0.1}, )" + ok_science + "}"),
              HasSubstr("telescope.obstructon = (unknown field)"));
  EXPECT_THAT(err(R"({"name": "t", "telescope": {"diameter_m": 8}, "science": {"wavelength_m": 2e-6}})"),
              HasSubstr("exactly one of camera_pixel_lambda_over_d"));
  EXPECT_THAT(err(R"({"name": "t", "telescope": {"diameter_m": 8}, )" + ok_science +
                  R"(, "atmosphere": {"r0_m": 0.1, "L0_m": 20, "layers": [{"cn2_fraction": 0.5}]}})"),
              HasSubstr("atmosphere"));
  try {
    LoadTelescopePreset("no-such-telescope");
    ADD_FAILURE();
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("paper-8m"));
  }
}

}  // namespace
}  // namespace aosr
