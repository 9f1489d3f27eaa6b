// Invalid scenes fail at parse time, before any computation, with a message that names the file, the field
// path, the bad value and what is allowed (scene_spec.hpp, io/config.hpp).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "../io/temp_dir.hpp"
#include "aosr/core/error.hpp"
#include "aosr/io/config.hpp"
#include "aosr/io/fits.hpp"
#include "aosr/scene/scene_spec.hpp"
#include "aosr/scene/telescope.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::AllOf;
using ::testing::HasSubstr;
using Json = nlohmann::json;

// The smallest valid scene: the paper's telescope, no AO, one USAF target on a 32-pixel frame.
Json BaseScene() {
  return Json{{"name", "base"},
              {"telescope", "paper-8m"},
              {"frames", 4},
              {"r", 2},
              {"detector", {{"frame_px", 32}}},
              {"objects", Json::array({Json{{"type", "usaf"}}})}};
}

// The error message of parsing `scene` as if it were the file `source`.
std::string ParseError(const Json& scene, const std::string& source = "mem.json") {
  return ErrorOf([&] { ParseScene(scene, source); });
}

void WriteJson(const std::string& path, const Json& j) {
  std::ofstream out(path);
  out << j.dump(2);
}

TEST(SceneSpecErrorsTest, BaseSceneIsValid) {
  EXPECT_EQ(ParseError(BaseScene()), "no exception");
}

TEST(SceneSpecErrorsTest, SkyOversamplingIsAnIntegerInRangeWithinTheGridLimit) {
  Json s = BaseScene();
  s["sky_oversampling"] = 0;
  EXPECT_THAT(ParseError(s), AllOf(HasSubstr("mem.json"), HasSubstr("sky_oversampling"), HasSubstr("0")));
  s["sky_oversampling"] = 17;
  EXPECT_THAT(ParseError(s), AllOf(HasSubstr("sky_oversampling"), HasSubstr("17")));
  s["sky_oversampling"] = 2.5;
  EXPECT_THAT(ParseError(s), HasSubstr("sky_oversampling"));
  s["sky_oversampling"] = 16;
  s["r"] = 16;
  s["detector"]["frame_px"] = 128;  // 16 * 16 * 128 = 32768 fine pixels per side
  EXPECT_THAT(ParseError(s), AllOf(HasSubstr("sky_oversampling"), HasSubstr("16384")));
  s["sky_oversampling"] = 4;
  s["r"] = 2;
  EXPECT_EQ(ParseError(s), "no exception");
  EXPECT_EQ(ParseScene(s, "mem.json").sky_oversampling, 4);
  EXPECT_EQ(ParseScene(BaseScene(), "mem.json").sky_oversampling, 1);
}

TEST(SceneSpecErrorsTest, SkyPointingIsCheckedFieldByField) {
  Json j = BaseScene();
  j["sky"] = {{"ra_deg", 10.0}, {"dec_deg", 95.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("mem.json: sky.dec_deg = 95"));
  j["sky"] = {{"ra_deg", -1.0}, {"dec_deg", 5.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("sky.ra_deg = -1"));
  j["sky"] = {{"dec_deg", 5.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("sky.ra_deg"));
  j["sky"] = {{"ra_deg", 1.0}, {"dec_deg", 5.0}, {"pa_deg", 3.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("sky.pa_deg = (unknown field)"));
  j["sky"] = {{"ra_deg", 1.0}, {"dec_deg", 5.0}, {"position_angle_deg", 30.0}};
  EXPECT_EQ(ParseError(j), "no exception");
  EXPECT_TRUE(ParseScene(j, "mem.json").sky.given);
  EXPECT_FALSE(ParseScene(BaseScene(), "mem.json").sky.given);
}

TEST(SceneSpecErrorsTest, UnknownFieldAtTopLevelNamesItAndTheCommentRule) {
  Json j = BaseScene();
  j["colour"] = "red";
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json: colour = (unknown field)"), HasSubstr("only the documented fields"),
                                   HasSubstr("\"comment\"")));
}

TEST(SceneSpecErrorsTest, UnknownNestedFieldsNameTheirFullPath) {
  Json j = BaseScene();
  j["detector"]["read_noise"] = 3;  // a typo of read_noise_e must not fall back to the default
  EXPECT_THAT(ParseError(j), HasSubstr("mem.json: detector.read_noise = (unknown field)"));

  j = BaseScene();
  j["objects"][0]["fil"] = 0.5;
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].fil = (unknown field)"));

  j = BaseScene();
  j["objects"][0]["flux"] = {{"peak_e", 10}, {"units", "adu"}};
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].flux.units = (unknown field)"));

  j = BaseScene();
  j["detector"]["bad_pixels"] = {{"fraction", 0.01}, {"sead", 3}};
  EXPECT_THAT(ParseError(j), HasSubstr("detector.bad_pixels.sead = (unknown field)"));

  // Closed-loop settings are not fields of the analytic mode.
  j = BaseScene();
  j["ao"] = {{"mode", "analytic"}, {"time_per_frame_s", 0.1}};
  EXPECT_THAT(ParseError(j), HasSubstr("ao.time_per_frame_s = (unknown field)"));

  j = BaseScene();
  j["offsets"] = {{"type", "design"}, {"frames", Json::array({Json{{"shift", {0, 0}}}, Json::object(),
                                                              Json::object(), Json::object()})}};
  EXPECT_THAT(ParseError(j), HasSubstr("offsets.frames[0].shift = (unknown field)"));
}

TEST(SceneSpecErrorsTest, MissingRequiredFieldsAreNamed) {
  for (const char* key : {"name", "telescope", "frames", "r", "detector", "objects"}) {
    Json j = BaseScene();
    j.erase(key);
    EXPECT_THAT(ParseError(j), AllOf(HasSubstr(std::string(key) + " = (missing)"), HasSubstr("required field")))
        << key;
  }
  Json j = BaseScene();
  j["objects"] = Json::array();
  EXPECT_THAT(ParseError(j), HasSubstr("objects = []; allowed: at least one object"));
}

TEST(SceneSpecErrorsTest, NegativeDiameterOfAnInlineTelescope) {
  Json tel = ReadJsonFile(DataDirectory() + "/telescopes/paper-8m.json");
  tel["telescope"]["diameter_m"] = -8.0;
  Json j = BaseScene();
  j["telescope"] = tel;
  // The inline preset is parsed as its own document, "<scene> (telescope)", with the preset's field paths.
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json (telescope): telescope.diameter_m = -8"),
                                   HasSubstr("a finite number > 0")));
}

TEST(SceneSpecErrorsTest, TelescopeFileThatDoesNotExist) {
  testing_io::TempDir tmp;
  Json j = BaseScene();
  j["telescope"] = "presets/mine.json";
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              AllOf(HasSubstr("telescope = \"" + tmp.File("presets/mine.json") + "\""),
                    HasSubstr("a preset name or an existing .json file")));
}

// paper-bench's camera pixel is 70.32 um / 400 mm = 3.74 lambda/D at 635 nm: the HR pixel must be at most
// lambda/D, so r >= 4.
TEST(SceneSpecErrorsTest, SuperResolutionFactorTooSmallForTheCameraPixel) {
  for (int r = 1; r <= 3; ++r) {
    Json j = BaseScene();
    j["telescope"] = "paper-bench";
    j["r"] = r;
    EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json: r = " + std::to_string(r)), HasSubstr("allowed: r >= 4"),
                                     HasSubstr("at most lambda/D")))
        << "r = " << r;
  }
  Json j = BaseScene();
  j["telescope"] = "paper-bench";
  j["r"] = 4;
  EXPECT_EQ(ParseError(j), "no exception");
}

TEST(SceneSpecErrorsTest, RangeErrorsNameTheAllowedRange) {
  Json j = BaseScene();
  j["r"] = 0;
  EXPECT_THAT(ParseError(j), HasSubstr("r = 0; allowed: an integer in [1, 16]"));
  j = BaseScene();
  j["frames"] = 2.5;
  EXPECT_THAT(ParseError(j), HasSubstr("frames = 2.5; allowed: an integer in [1, 1024]"));
  j = BaseScene();
  j["detector"]["frame_px"] = {32.5, 32};
  EXPECT_THAT(ParseError(j), HasSubstr("detector.frame_px = [32.5,32]; allowed: whole numbers of pixels"));
  j = BaseScene();
  j["detector"]["frame_px"] = 4;
  EXPECT_THAT(ParseError(j), HasSubstr("detector.frame_px = 4; allowed: an integer in [8, 4096]"));
}

TEST(SceneSpecErrorsTest, MissingImageFileIsResolvedAgainstTheSceneFolder) {
  testing_io::TempDir tmp;
  Json j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "image"}, {"path", "images/galaxy.png"}}});
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              AllOf(HasSubstr("objects[0].path = \"" + tmp.File("images/galaxy.png") + "\""),
                    HasSubstr("an existing FITS/PNG/TIFF file")));
}

// Found by fuzz_scene (fuzz/regressions/scene/): a file name longer than the OS allows (NAME_MAX) made
// std::filesystem throw filesystem_error ("File name too long") out of the parser instead of the field's error.
TEST(SceneSpecErrorsTest, FileNamesTooLongForTheOsAreMissingFiles) {
  const std::string long_name(300, 'a');
  Json j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "image"}, {"path", long_name + ".png"}}});
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("objects[0].path = \""), HasSubstr("an existing FITS/PNG/TIFF file")));
  j = BaseScene();
  j["telescope"] = long_name;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("LoadTelescopePreset"), HasSubstr(long_name), HasSubstr("paper-8m")));
  j = BaseScene();
  j["telescope"] = long_name + ".json";
  EXPECT_THAT(ParseError(j), HasSubstr("a preset name or an existing .json file"));
  j = BaseScene();
  j["offsets"] = Json{{"type", "design"}, {"file", long_name}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("offsets.file"), HasSubstr("an existing design .json file")));
  j = BaseScene();
  j["detector"]["bad_pixels"] = Json{{"file", long_name}};
  EXPECT_THAT(ParseError(j), HasSubstr("detector.bad_pixels.file"));
}

TEST(SceneSpecErrorsTest, ImageOptionsAreChoices) {
  testing_io::TempDir tmp;
  WriteFits(tmp.File("object.fits"), Image::Ones(8, 8));
  Json j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "image"}, {"path", "object.fits"}, {"fit", "zoom"}}});
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              HasSubstr("objects[0].fit = \"zoom\"; allowed: one of crop, stretch"));
  j["objects"][0]["fit"] = "crop";
  j["objects"][0]["background"] = "mode";
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              HasSubstr("objects[0].background = \"mode\"; allowed: one of none, median, border-median, minimum"));
}

TEST(SceneSpecErrorsTest, MissingDesignFile) {
  testing_io::TempDir tmp;
  Json j = BaseScene();
  j["offsets"] = {{"type", "design"}, {"file", "designs/best.json"}};
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              AllOf(HasSubstr("offsets.file = \"" + tmp.File("designs/best.json") + "\""),
                    HasSubstr("an existing design .json file")));
}

TEST(SceneSpecErrorsTest, DesignWithTheWrongNumberOfFrames) {
  testing_io::TempDir tmp;
  Json design = {{"name", "three"}, {"frames", Json::array()}};
  for (int i = 0; i < 3; ++i) {
    DmOffset o;
    o.shift_x_px = 0.25 * i;
    design["frames"].push_back(DmOffsetToJson(o));
  }
  WriteJson(tmp.File("three.json"), design);
  Json j = BaseScene();  // frames = 4
  j["offsets"] = {{"type", "design"}, {"file", "three.json"}};
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              HasSubstr("offsets.file = 3 frames; allowed: exactly the scene's frames = 4"));

  j["offsets"] = {{"type", "design"}, {"frames", design["frames"]}};
  EXPECT_THAT(ParseError(j), HasSubstr("offsets.frames = 3 frames; allowed: exactly the scene's frames = 4"));

  j["offsets"] = {{"type", "design"}, {"frames", design["frames"]}, {"file", "three.json"}};
  EXPECT_THAT(ParseError(j), HasSubstr("offsets = 2 of frames, file; allowed: exactly one of them"));
}

TEST(SceneSpecErrorsTest, DesignFramesAreValidated) {
  testing_io::TempDir tmp;
  WriteJson(tmp.File("empty.json"), Json{{"frames", Json::array()}});
  EXPECT_THAT(ErrorOf([&] { LoadDesignFile(tmp.File("empty.json")); }),
              HasSubstr("frames = []; allowed: one entry per exposure"));
  WriteJson(tmp.File("typo.json"), Json{{"frame", Json::array({Json::object()})}});
  EXPECT_THAT(ErrorOf([&] { LoadDesignFile(tmp.File("typo.json")); }), HasSubstr("frames = (missing)"));

  Json j = BaseScene();
  j["frames"] = 1;
  j["offsets"] = {{"type", "design"},
                  {"frames", Json::array({Json{{"zernike", Json::array({Json{{"noll", 1}, {"rms_nm", 10}}})}}})}};
  EXPECT_THAT(ParseError(j), HasSubstr("offsets.frames[0].zernike = noll 1; allowed: Noll indices >= 2"));
  j["offsets"] = {{"type", "design"}, {"frames", Json::array({Json{{"shift_px", {0.5}}}})}};
  EXPECT_THAT(ParseError(j), HasSubstr("offsets.frames[0].shift_px = [0.5]; allowed: an array of 2 numbers"));
  j["offsets"] = {{"type", "dither"}};
  EXPECT_THAT(ParseError(j), HasSubstr("offsets.type = \"dither\"; allowed: one of none, raster, design"));
}

TEST(SceneSpecErrorsTest, FluxSpecNeedsExactlyOneKey) {
  Json j = BaseScene();
  j["objects"][0]["flux"] = {{"total_e", 1e4}, {"peak_e", 100}};
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].flux = 2 of total_e, peak_e, magnitude; allowed: exactly one of them"));
  j["objects"][0]["flux"] = Json::object();
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].flux = 0 of total_e, peak_e, magnitude; allowed: exactly one of them"));
  j["objects"][0]["flux"] = {{"total_e", -5}};
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].flux.total_e = -5; allowed: a finite number > 0"));
  j["objects"][0]["flux"] = 100;
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].flux = 100; allowed: a JSON object"));
}

TEST(SceneSpecErrorsTest, MagnitudesNeedPhotometry) {
  // A component normalised to a magnitude.
  Json j = BaseScene();
  j["objects"][0]["flux"] = {{"magnitude", 18}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json: photometry"),
                                   HasSubstr("photometry.band or photometry.zero_point_mag")));
  // A random star field with its luminosity function in magnitudes (converted while parsing the object).
  j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "stars"}, {"count", 10}, {"magnitude_range", {15, 20}}}});
  EXPECT_THAT(ParseError(j), HasSubstr("photometry.band"));
  // A catalogue star given by magnitude.
  j["objects"] = Json::array(
      {Json{{"type", "stars"}, {"catalogue", Json::array({Json{{"y_px", 3}, {"x_px", 4}, {"magnitude", 17}}})}}});
  EXPECT_THAT(ParseError(j), HasSubstr("photometry.band"));
  // A sky in magnitudes per square arcsecond.
  j = BaseScene();
  j["detector"]["sky_mag_per_arcsec2"] = 13.0;
  EXPECT_THAT(ParseError(j), HasSubstr("detector.sky_mag_per_arcsec2 = 13; allowed: a sky magnitude only with "
                                       "photometry.band or photometry.zero_point_mag"));
  // With a band all of them parse.
  j["photometry"] = {{"band", "K"}};
  j["objects"][0]["flux"] = {{"magnitude", 18}};
  EXPECT_EQ(ParseError(j), "no exception");
}

TEST(SceneSpecErrorsTest, PhotometryBandIsAKnownVegaBand) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "k"}};  // case-sensitive
  EXPECT_THAT(ParseError(j), HasSubstr("photometry.band = \"k\"; allowed: one of U, B, V, R, I, J, H, K, Ks"));
}

TEST(SceneSpecErrorsTest, StarMagnitudesExcludeAFluxNormalisation) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "K"}};
  j["objects"] = Json::array(
      {Json{{"type", "stars"}, {"count", 10}, {"magnitude_range", {15, 20}}, {"flux", {{"total_e", 1e5}}}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].flux = (given); allowed: no flux normalisation when the stars' "
                                       "brightness is given in magnitudes"));
  j["objects"] = Json::array({Json{{"type", "stars"}, {"count", 10}, {"magnitude_range", {20, 15}}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].magnitude_range = [20, 15]; allowed: [low, high] with low < high"));
  j["objects"] = Json::array(
      {Json{{"type", "stars"}, {"count", 10}, {"magnitude_range", {15, 20}}, {"flux_range_e", {1, 10}}}});
  EXPECT_THAT(ParseError(j), HasSubstr("one of flux_range_e and magnitude_range"));
  j["objects"] = Json::array(
      {Json{{"type", "stars"}, {"catalogue", Json::array({Json{{"y_px", 3}, {"x_px", 4}, {"magnitude", 17}, {"flux_e", 5}}})}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].catalogue[0] = 2 of flux_e, magnitude; allowed: exactly one of them"));
  // Catalogue positions are camera pixels of the 32-pixel frame.
  j["objects"] = Json::array(
      {Json{{"type", "stars"}, {"catalogue", Json::array({Json{{"y_px", 40}, {"x_px", 4}, {"flux_e", 5}}})}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].catalogue[0].y_px = 40; allowed: a number in [-0.5, 31.5]"));
}

TEST(SceneSpecErrorsTest, UnknownObjectTypeListsTheTypes) {
  Json j = BaseScene();
  j["objects"][0]["type"] = "nebula";
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].type = \"nebula\"; allowed: one of usaf, demo, stars, galaxies, "
                                       "dead-leaves, image"));
}

TEST(SceneSpecErrorsTest, ObjectOptionsAreChecked) {
  Json j = BaseScene();
  j["objects"][0]["first_group"] = 2;
  j["objects"][0]["last_group"] = 0;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("objects[0] = (inconsistent)"), HasSubstr("first_group")));
  j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "galaxies"}, {"count", 5}, {"margin_px", 16}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].margin_px = 16; allowed: less than half the smaller frame side"));
  j["objects"] = Json::array({Json{{"type", "dead-leaves"}, {"radius_range_px", {4, 2}}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].radius_range_px = [4, 2]; allowed: [low, high] with low < high"));
  j["objects"] = Json::array({Json{{"type", "stars"}}});
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].count = (missing)"));
}

TEST(SceneSpecErrorsTest, NoiseOptionsOnlyWithTheirNoiseModel) {
  Json j = BaseScene();
  j["detector"]["noise"] = "peak-fraction";
  j["detector"]["read_noise_e"] = 5;
  EXPECT_THAT(ParseError(j), HasSubstr("detector.read_noise_e = (given); allowed: photon_noise and read_noise_e only "
                                       "with noise = \"physical\""));
  j["detector"].erase("read_noise_e");
  j["detector"]["photon_noise"] = false;
  EXPECT_THAT(ParseError(j), HasSubstr("detector.photon_noise = (given)"));

  j = BaseScene();
  j["detector"]["peak_noise_fraction"] = 0.01;  // noise defaults to "physical"
  EXPECT_THAT(ParseError(j), HasSubstr("detector.peak_noise_fraction = (given); allowed: only with noise = "
                                       "\"peak-fraction\""));
  j["detector"]["noise"] = "none";
  EXPECT_THAT(ParseError(j), HasSubstr("detector.peak_noise_fraction = (given)"));

  j = BaseScene();
  j["detector"]["noise"] = "gaussian";
  EXPECT_THAT(ParseError(j), HasSubstr("detector.noise = \"gaussian\"; allowed: one of physical, peak-fraction, none"));
}

TEST(SceneSpecErrorsTest, DetectorConsistency) {
  Json j = BaseScene();
  j["photometry"] = {{"band", "K"}};
  j["detector"]["background_e_per_s"] = 10;
  j["detector"]["sky_mag_per_arcsec2"] = 13;
  EXPECT_THAT(ParseError(j), HasSubstr("detector.background_e_per_s = (both given); allowed: one of "
                                       "background_e_per_s and sky_mag_per_arcsec2"));
  j = BaseScene();
  j["detector"]["bias_adu"] = 1000;
  j["detector"]["saturation_adu"] = 500;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("detector = (inconsistent)"), HasSubstr("saturation_adu")));
}

// paper-8m samples its pupil with 128 pixels, so its PSF repeats every 128 lambda/D.
TEST(SceneSpecErrorsTest, PsfWindowWiderThanThePupilPeriod) {
  Json j = BaseScene();
  j["psf"] = {{"window_lambda_over_d", 200.0}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json: psf = 200 lambda/D (400 HR px)"),
                                   HasSubstr("at most the pupil grid's period, 128 lambda/D (telescope pupil_px)")));
  j["psf"] = {{"size_px", 300}};  // 300 HR pixels of lambda/(2D)
  EXPECT_THAT(ParseError(j), HasSubstr("psf = 150 lambda/D (300 HR px)"));
  j["psf"] = {{"size_px", 256}};  // exactly one period is allowed
  EXPECT_EQ(ParseError(j), "no exception");
  j["psf"] = {{"size_px", 63}};
  EXPECT_THAT(ParseError(j), HasSubstr("psf.size_px = 63; allowed: an even number of HR pixels"));
  j["psf"] = {{"size_px", 64}, {"window_lambda_over_d", 32}};
  EXPECT_THAT(ParseError(j), HasSubstr("psf.size_px = (both given); allowed: one of size_px and window_lambda_over_d"));
}

TEST(SceneSpecErrorsTest, AoModeNeedsTheTelescopeSections) {
  Json j = BaseScene();
  j["telescope"] = "paper-bench";  // an AO section but no atmosphere
  j["r"] = 4;
  j["ao"] = {{"mode", "analytic"}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("ao.mode = \"analytic\"; allowed: \"none\" or \"closed-loop\""),
                                   HasSubstr("lacks an \"atmosphere\" or \"ao\" section")));
  j = BaseScene();
  j["ao"] = {{"mode", "closed-loop"}, {"time_per_frame_s", 0.001}, {"psf_every_steps", 4}};  // 0.8 loop frames
  EXPECT_THAT(ParseError(j), HasSubstr("ao.time_per_frame_s = 0.001; allowed: at least psf_every_steps loop frames"));
  j["ao"] = {{"mode", "closed-loop"}, {"sensor", "pyramid"}};
  EXPECT_THAT(ParseError(j), HasSubstr("ao.sensor = \"pyramid\"; allowed: one of ideal, geometric, diffractive"));
}

TEST(SceneSpecErrorsTest, DmGainOnlyInRangeAndOnlyForTheClosedLoop) {
  Json j = BaseScene();
  j["ao"] = {{"mode", "closed-loop"}, {"dm_gain", 3.0}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("ao.dm_gain = 3"), HasSubstr("[0.5, 2]")));
  j["ao"] = {{"mode", "closed-loop"}, {"dm_gain", 0.4}};
  EXPECT_THAT(ParseError(j), HasSubstr("ao.dm_gain = 0.4"));
  j["ao"] = {{"mode", "analytic"}, {"dm_gain", 1.1}};  // the analytic model has no DM to mis-calibrate
  EXPECT_THAT(ParseError(j), HasSubstr("dm_gain"));
  j["ao"] = {{"mode", "closed-loop"}, {"dm_gain", 1.1}};
  EXPECT_EQ(ParseError(j), "no exception");
}

TEST(SceneSpecErrorsTest, OffsetCalibrationAndAntitheticOnlyForTheClosedLoop) {
  Json j = BaseScene();
  j["ao"] = {{"mode", "closed-loop"}, {"offset_calibration", "measured"}};
  EXPECT_THAT(ParseError(j), HasSubstr("ao.offset_calibration = \"measured\"; allowed: one of on-sky, flat"));
  j["ao"] = {{"mode", "closed-loop"}, {"antithetic", "yes"}};
  EXPECT_THAT(ParseError(j), HasSubstr("ao.antithetic"));
  j["ao"] = {{"mode", "analytic"}, {"antithetic", true}};  // one analytic PSF has no realisation to pair
  EXPECT_THAT(ParseError(j), HasSubstr("antithetic"));
  j["ao"] = {{"mode", "analytic"}, {"offset_calibration", "flat"}};
  EXPECT_THAT(ParseError(j), HasSubstr("offset_calibration"));
  j["ao"] = {{"mode", "closed-loop"}, {"offset_calibration", "flat"}, {"antithetic", false}};
  EXPECT_EQ(ParseError(j), "no exception");
}

TEST(SceneSpecErrorsTest, StaticAberrationsNeedNollAtLeastTwo) {
  Json j = BaseScene();
  j["static_aberrations"] = Json::array({Json{{"noll", 1}, {"rms_nm", 50}}});
  EXPECT_THAT(ParseError(j), HasSubstr("static_aberrations[0].noll = 1; allowed: a Noll index >= 2"));
}

TEST(SceneSpecErrorsTest, BadPixelFileOfTheWrongShape) {
  testing_io::TempDir tmp;
  WriteFits(tmp.File("mask16.fits"), Image::Ones(16, 16));
  Json j = BaseScene();  // 32 x 32 frame
  j["detector"]["bad_pixels"] = {{"file", "mask16.fits"}};
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              AllOf(HasSubstr("detector.bad_pixels.file = " + ToString(Shape{16, 16})),
                    HasSubstr("a mask of the frame's shape " + ToString(Shape{32, 32}))));

  Image grey = Image::Ones(32, 32);
  grey(3, 4) = 0.5;
  WriteFits(tmp.File("grey.fits"), grey);
  j["detector"]["bad_pixels"] = {{"file", "grey.fits"}};
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")), HasSubstr("a mask holding only 0 (bad) and 1 (good)"));

  j["detector"]["bad_pixels"] = {{"file", "absent.fits"}};
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              AllOf(HasSubstr("detector.bad_pixels.file = \"" + tmp.File("absent.fits") + "\""),
                    HasSubstr("an existing FITS/PNG/TIFF mask")));

  j["detector"]["bad_pixels"] = {{"file", "grey.fits"}, {"fraction", 0.01}};
  EXPECT_THAT(ParseError(j, tmp.File("scene.json")),
              HasSubstr("detector.bad_pixels = 2 of fraction, file; allowed: exactly one of them"));
}

TEST(SceneSpecErrorsTest, LoadSceneNamesTheFile) {
  testing_io::TempDir tmp;
  EXPECT_THAT(ErrorOf<IoError>([&] { LoadScene(tmp.File("absent.json")); }), HasSubstr(tmp.File("absent.json")));
  testing_io::WriteBytes(tmp.File("broken.json"), "{\"name\": ");
  EXPECT_THAT(ErrorOf([&] { LoadScene(tmp.File("broken.json")); }),
              AllOf(HasSubstr(tmp.File("broken.json")), HasSubstr("malformed JSON")));
  Json j = BaseScene();
  j["r"] = 0;
  WriteJson(tmp.File("bad_r.json"), j);
  EXPECT_THAT(ErrorOf([&] { LoadScene(tmp.File("bad_r.json")); }), HasSubstr(tmp.File("bad_r.json") + ": r = 0"));
}

}  // namespace
}  // namespace aosr

namespace aosr {
namespace AOSR_TEST_NS {

// Checks that used to fire only when the scene ran now fail at parse time (so `--plan` refuses them too).
TEST(SceneSpecErrorsTest, DemoObjectNeedsA64PixelHrFrame) {
  Json j = BaseScene();
  j["detector"]["frame_px"] = 16;
  j["objects"] = Json::array({Json{{"type", "demo"}}});
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("objects[0].type = demo"), HasSubstr("at least 64 x 64")));
  j["detector"]["frame_px"] = 32;  // 64 HR pixels at r = 2
  EXPECT_EQ(ParseError(j), "no exception");
}

TEST(SceneSpecErrorsTest, OverpackedHardCoreStarFieldFailsAtParse) {
  Json j = BaseScene();
  j["objects"] = Json::array({Json{{"type", "stars"}, {"count", 500}, {"min_separation_px", 3}}});
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("objects[0].min_separation_px = 3"), HasSubstr("packing fraction")));
  j["objects"][0]["count"] = 20;
  EXPECT_EQ(ParseError(j), "no exception");
}

// psf_field: only with AO correction; every node within what the mode can compute (the analytic PSD grid's
// reach); a grid spacing of at most θ0; the grid's own shape.
TEST(SceneSpecErrorsTest, BadPsfField) {
  Json j = BaseScene();
  j["psf_field"] = {{"grid", 2}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json: psf_field"), HasSubstr("ao.mode analytic or closed-loop")));
  j["ao"] = {{"mode", "analytic"}};
  EXPECT_EQ(ParseError(j), "no exception");
  j["psf_field"] = {{"grid", 2}, {"guide_star_arcsec", {2000.0, 0.0}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("psf_field.guide_star_arcsec = 2000, 0"), HasSubstr("in analytic mode")));
  j["psf_field"] = {{"grid", 2}, {"guide_star_arcsec", {1.0}}};
  EXPECT_THAT(ParseError(j), HasSubstr("psf_field.guide_star_arcsec"));
  j["psf_field"] = {{"grid", {2, 0}}};
  EXPECT_THAT(ParseError(j), HasSubstr("psf_field.grid"));
  j["psf_field"] = {{"grid", {2.5, 2}}};
  EXPECT_THAT(ParseError(j), HasSubstr("whole numbers"));
  j["psf_field"] = {{"grid", 2}, {"guide", 1}};
  EXPECT_THAT(ParseError(j), HasSubstr("psf_field.guide"));
  // 512 camera px of lambda/D at K span 29 arcsec, more than theta0 (about 20 arcsec at K for paper-8m): one
  // node is too coarse, and the error says how many are needed.
  j["detector"]["frame_px"] = 512;
  j["psf_field"] = {{"grid", 1}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("psf_field.grid = 1 x 1"), HasSubstr("at least 3 x 3 nodes"),
                                   HasSubstr("isoplanatic angle theta0")));
  j["psf_field"] = {{"grid", 3}};
  EXPECT_EQ(ParseError(j), "no exception");
}


// ---- Sequences, variations and planets (SequenceSpec, ObjectVariation, planet objects) ----------------------

// Four phases on a 32-pixel frame; frame time 0.25 s.
// BaseScene as a sequence of 8 exposures with one star.
Json SequenceScene() {
  Json j = BaseScene();
  j["sequence"] = {{"frames", 8}};
  j["objects"] = Json::array({Json{{"type", "stars"}, {"catalogue", {{{"y_px", 10}, {"x_px", 10}, {"flux_e", 100}}}}}});
  return j;
}

TEST(SceneSpecSequenceErrors, SequenceSection) {
  Json j = SequenceScene();
  j["sequence"]["frames"] = 3;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("mem.json"), HasSubstr("sequence.frames = 3"), HasSubstr("N = 4 phases")));
  j = SequenceScene();
  j["sequence"]["frames"] = 0;
  EXPECT_THAT(ParseError(j), HasSubstr("sequence.frames = 0"));
  j = SequenceScene();
  j["sequence"]["frame_interval_s"] = 0.2;
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("sequence.frame_interval_s = 0.2"), HasSubstr("frame time"), HasSubstr("0.25")));
  j = SequenceScene();
  j["sequence"]["rate_hz"] = 50;
  EXPECT_THAT(ParseError(j), HasSubstr("rate_hz"));
  j = SequenceScene();
  j["sequence"]["start_s"] = "soon";
  EXPECT_THAT(ParseError(j), HasSubstr("sequence.start_s"));
}

TEST(SceneSpecSequenceErrors, Variation) {
  Json j = SequenceScene();
  j.erase("sequence");
  j["objects"][0]["variation"] = {{"velocity_px_per_s", {1.0, 0.0}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("objects[0].variation"), HasSubstr("\"sequence\" section")));
  j = SequenceScene();
  j["objects"][0]["variation"] = {{"velocity_px_per_s", {1.0}}};
  EXPECT_THAT(ParseError(j), HasSubstr("velocity_px_per_s"));
  j["objects"][0]["variation"] = {{"spin", 1.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("spin"));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "sine"}, {"period_s", 1.0}, {"amplitude", 1.5}}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("light_curve.amplitude = 1.5"), HasSubstr("1")));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "sine"}, {"period_s", 0.0}, {"amplitude", 0.5}}}};
  EXPECT_THAT(ParseError(j), HasSubstr("light_curve.period_s = 0"));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "blink"}}}};
  EXPECT_THAT(ParseError(j), HasSubstr("light_curve.kind"));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "table"}, {"times_s", {0.0, 1.0}}, {"factors", {1.0}}}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("light_curve.factors"), HasSubstr("one per time (2)")));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "table"}, {"times_s", {0.0, 0.0}}, {"factors", {1.0, 2.0}}}}};
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("light_curve.times_s"), HasSubstr("increasing")));
  j["objects"][0]["variation"] = {{"light_curve", {{"kind", "table"}, {"times_s", {0.0, 1.0}}, {"factors", {1.0, -2.0}}}}};
  EXPECT_THAT(ParseError(j), HasSubstr("light_curve.factors"));
}

TEST(SceneSpecSequenceErrors, Planet) {
  Json j = SequenceScene();
  j["objects"] = Json::array({Json{{"type", "planet"}}});
  EXPECT_THAT(ParseError(j), HasSubstr("radius_px"));
  j["objects"][0]["radius_px"] = -2.0;
  EXPECT_THAT(ParseError(j), HasSubstr("objects[0].radius_px = -2"));
  j["objects"][0]["radius_px"] = 5.0;
  j["objects"][0]["limb_darkening"] = 1.2;
  EXPECT_THAT(ParseError(j), HasSubstr("limb_darkening = 1.2"));
  j["objects"][0]["limb_darkening"] = 0.5;
  j["objects"][0]["sub_observer_latitude_deg"] = 95;
  EXPECT_THAT(ParseError(j), HasSubstr("sub_observer_latitude_deg = 95"));
  j["objects"][0]["sub_observer_latitude_deg"] = 0;
  j["objects"][0]["texture"] = {{"band_contrast", 1.0}};
  EXPECT_THAT(ParseError(j), HasSubstr("texture.band_contrast = 1"));
  j["objects"][0]["texture"] = {{"stripes", 3}};
  EXPECT_THAT(ParseError(j), HasSubstr("stripes"));
  j["objects"][0]["texture"] = Json::object();
  j["objects"][0]["texture_path"] = "missing.fits";
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("texture"), HasSubstr("one of texture and texture_path")));
  j["objects"][0].erase("texture");
  EXPECT_THAT(ParseError(j), AllOf(HasSubstr("texture_path"), HasSubstr("missing.fits"), HasSubstr("an existing")));
  j["objects"][0].erase("texture_path");
  j["objects"][0]["rotation_period_s"] = 1e-12;
  EXPECT_THAT(ParseError(j), HasSubstr("rotation_period_s"));
  j["objects"][0]["rotation_period_s"] = 10.0;
  EXPECT_NO_THROW(ParseScene(j, "mem.json"));
}

// The exposure accessors refuse an exposure outside the sequence (they index the phases' offsets).
TEST(SceneSpecSequenceErrors, ExposureAccessorsRange) {
  const SceneSpec s = ParseScene(SequenceScene(), "mem.json");
  EXPECT_EQ(s.Exposures(), 8);
  EXPECT_NO_THROW(s.ExposureOffset(7));
  EXPECT_THAT(ErrorOf([&] { s.ExposureOffset(8); }), AllOf(HasSubstr("SceneSpec::ExposureOffset"), HasSubstr("j = 8"), HasSubstr("0..7")));
  EXPECT_THAT(ErrorOf([&] { s.ExposureOffset(-1); }), HasSubstr("j = -1"));
  EXPECT_THAT(ErrorOf([&] { s.ExposureTime(8); }), AllOf(HasSubstr("SceneSpec::ExposureTime"), HasSubstr("j = 8")));
  EXPECT_THAT(ErrorOf([&] { s.ExposureTime(-3); }), HasSubstr("j = -3"));
}

}  // namespace
}  // namespace aosr
