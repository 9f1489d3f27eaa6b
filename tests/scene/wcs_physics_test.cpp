// Sky coordinates of a simulated dataset (io/wcs.hpp, scene/dataset.hpp): a star's sky position read through
// a camera frame's WCS at the position where the frame actually shows it must be the position read through the
// HR grid's WCS at the star's HR (truth) position. Frame 0 carries a DM image shift and frame 1 none, so a
// wrong sign of the offset in CRPIX_HR = (CRPIX − ½)·r + ½ − d would miss by 2d (1.5 HR px here).
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/io/wcs.hpp"
#include "aosr/scene/dataset.hpp"
#include "dataset_fixture.hpp"
#include "io/temp_dir.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using testing_io::TempDir;

// A well-sampled camera (pixel λ/4D, FWHM ≈ 4 px), no noise, one bright star, frame 0 shifted by the DM.
nlohmann::json StarScene() {
  return {{"name", "wcs-star"},
          {"telescope",
           {{"name", "wcs-test"},
            {"telescope", {{"diameter_m", 8.0}, {"obstruction", 0.0}, {"pupil_px", 128}}},
            {"science", {{"wavelength_m", 2.2e-6}, {"camera_pixel_lambda_over_d", 0.25}}}}},
          {"frames", 2},
          {"r", 2},
          {"psf", {{"window_lambda_over_d", 8}}},
          {"ao", {{"mode", "none"}}},
          {"offsets",
           {{"type", "design"},
            {"frames", nlohmann::json::array({{{"shift_px", {0.37, -0.21}}}, {{"shift_px", {0.0, 0.0}}}})}}},
          {"sky", {{"ra_deg", 150.1}, {"dec_deg", -30.2}, {"position_angle_deg", 25.0}}},
          {"detector", {{"frame_px", 48}, {"noise", "none"}, {"saturation", false}}},
          {"objects",
           nlohmann::json::array(
               {{{"type", "stars"},
                 {"catalogue", nlohmann::json::array({{{"y_px", 20.3}, {"x_px", 27.6}, {"flux_e", 1e5}}})}}})}};
}

// Gaussian-windowed centroid iterated to its fixed point Σ w(c − μ)(c − μ) I(c) = 0: the centre of a
// symmetric, well-sampled image (the window's spectrum is far narrower than the sampling's margin).
PixelCoord WindowedCentroid(const Image& img, PixelCoord start, double sigma_px) {
  PixelCoord mu = start;
  for (int it = 0; it < 200; ++it) {
    double s = 0, sy = 0, sx = 0;
    for (Index y = 0; y < img.rows(); ++y)
      for (Index x = 0; x < img.cols(); ++x) {
        const double w = std::exp(-((y - mu.y) * (y - mu.y) + (x - mu.x) * (x - mu.x)) / (2 * sigma_px * sigma_px));
        s += w * img(y, x);
        sy += w * img(y, x) * y;
        sx += w * img(y, x) * x;
      }
    const PixelCoord next{sy / s, sx / s};
    const double step = std::hypot(next.y - mu.y, next.x - mu.x);
    mu = next;
    if (step < 1e-12) break;
  }
  return mu;
}

TEST(WcsPhysicsTest, AStarHasOneSkyPositionInTheFramesAndOnTheHrGrid) {
  TempDir dir;
  const auto w = test::SimulateInto(dir.File("scene.json"), StarScene(), dir.File("out"));
  const Dataset d = LoadDataset(dir.File("out"));
  ASSERT_TRUE(d.wcs.has_value());
  const std::optional<Wcs> hr = d.HrWcs();
  ASSERT_TRUE(hr.has_value());
  ASSERT_EQ(d.stars.size(), 1u);
  const PixelCoord star_hr{d.stars[0].y, d.stars[0].x};
  const double hr_pixel_deg = hr->PixelScaleDeg(0);
  EXPECT_NEAR(hr_pixel_deg * M_PI / 180, d.camera_pixel_rad / d.r, 1e-12 * d.camera_pixel_rad);

  // The truth file's WCS is the HR grid's, with the pointing at its centre.
  const Wcs truth = WcsFromHeader(ReadFits(dir.File("out/truth.fits")).header);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(truth.crpix[i], hr->crpix[i], 1e-9);
  const SkyCoord centre = PixelToSky(truth, {(d.hr_frame.rows - 1) / 2.0, (d.hr_frame.cols - 1) / 2.0});
  EXPECT_NEAR(centre.ra_deg, 150.1, 1e-12);
  EXPECT_NEAR(centre.dec_deg, -30.2, 1e-12);
  const SkyCoord star_sky = PixelToSky(*hr, star_hr);

  // Where each noiseless frame shows the star, through that frame's WCS: frame 0's is the dataset's, frame
  // i's is LrWcs of the HR grid's with its own shift (both frames here: i = 0 via the file, i = 1 derived).
  const ImageStack expected = ReadFits(dir.File("out/expected.fits")).planes;
  const double r = d.r;
  for (int i = 0; i < 2; ++i) {
    const double dy = d.offsets[i].shift_y_px * r, dx = d.offsets[i].shift_x_px * r;
    const Wcs frame_wcs = i == 0 ? *d.wcs : LrWcs(*hr, d.r, dy, dx);
    const PixelCoord guess{(star_hr.y + 0.5) / r - 0.5, (star_hr.x + 0.5) / r - 0.5};
    const PixelCoord seen = WindowedCentroid(expected[i], guess, 2.5);
    const double miss_hr = AngularSeparationDeg(PixelToSky(frame_wcs, seen), star_sky) / hr_pixel_deg;
    EXPECT_LT(miss_hr, 0.02) << "frame " << i << ": star seen at LR (" << seen.y << ", " << seen.x << ")";
    // The shift is real: the frame shows the star displaced by it.
    EXPECT_NEAR(seen.y, (star_hr.y + dy + 0.5) / r - 0.5, 0.01) << i;
    EXPECT_NEAR(seen.x, (star_hr.x + dx + 0.5) / r - 0.5, 0.01) << i;
  }
  // The other sign would put frame 0's star 2·|d| away.
  const Wcs wrong = LrWcs(*hr, d.r, -d.offsets[0].shift_y_px * r, -d.offsets[0].shift_x_px * r);
  const PixelCoord seen0 = WindowedCentroid(expected[0], {20.3, 27.6}, 2.5);
  EXPECT_GT(AngularSeparationDeg(PixelToSky(wrong, seen0), star_sky) / hr_pixel_deg, 1.0);
}

TEST(WcsPhysicsTest, SkyPointingDefaultsAndManifestWcsOverridesTheFrames) {
  TempDir dir;
  nlohmann::json scene = StarScene();
  scene.erase("sky");
  test::SimulateInto(dir.File("scene.json"), scene, dir.File("out"));
  const FitsData frames = ReadFits(dir.File("out/frames.fits"));
  EXPECT_FALSE(frames.header.GetBool("SKYGIVEN"));
  const Wcs lr = WcsFromHeader(frames.header);
  EXPECT_NEAR(lr.crval[0], 0.0, 1e-12);
  EXPECT_NEAR(lr.crval[1], 0.0, 1e-12);
  EXPECT_LT(lr.cd[0][0], 0.0);  // north up, east left
  EXPECT_GT(lr.cd[1][1], 0.0);
  EXPECT_EQ(frames.header.GetString("BUNIT"), "adu");
  EXPECT_FALSE(HasWcs(ReadFits(dir.File("out/psfs.fits")).header));  // kernels are not sky images

  // A manifest's "wcs" replaces the frames' own; null removes it.
  nlohmann::json m = ReadJsonFile(dir.File("out/manifest.json"));
  m["wcs"] = {{"CTYPE1", "RA---TAN"}, {"CTYPE2", "DEC--TAN"}, {"CRPIX1", 24.5}, {"CRPIX2", 24.5},
              {"CRVAL1", 10.0},       {"CRVAL2", 20.0},       {"CDELT1", -1e-5}, {"CDELT2", 1e-5}};
  test::WriteJson(dir.File("out/manifest.json"), m);
  const Dataset d = LoadDataset(dir.File("out"));
  ASSERT_TRUE(d.wcs);
  EXPECT_EQ(d.wcs->crval[0], 10.0);
  EXPECT_EQ(d.wcs->cd[0][0], -1e-5);
  m["wcs"] = nullptr;
  test::WriteJson(dir.File("out/manifest.json"), m);
  EXPECT_FALSE(LoadDataset(dir.File("out")).wcs);
  EXPECT_FALSE(LoadDataset(dir.File("out")).HrWcs());
  FitsHeader h;
  SetHrImageKeywords(LoadDataset(dir.File("out")), "electron", &h);
  EXPECT_FALSE(HasWcs(h));
  EXPECT_EQ(h.GetString("BUNIT"), "electron");
}

}  // namespace
}  // namespace aosr
