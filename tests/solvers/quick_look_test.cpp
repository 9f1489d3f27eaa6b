// The live quick-look (quick_look.hpp) against a writer thread producing frames at 50 per second: every file
// gives exactly one event with the right status (used; late when older than its phase's frame; rejected for a
// wrong shape, a missing phase keyword or a phase out of range; incomplete when it is never finished), a file
// written in place in two parts is used once and whole, a missing phase keeps its previous frame, and every
// output equals the streaming engine fed the same frames directly (which video_stream_test checks against the
// batch reconstruction); quicklook.fits holds the last output with the HR WCS, quicklook.png exists.
#include "aosr/solvers/quick_look.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <thread>

#include "aosr/io/fits.hpp"
#include "support/testing.hpp"
#include "support/video_sequence.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

struct LiveDirs {
  fs::path root;
  LiveDirs() {
    root = fs::temp_directory_path() / ("aosr_quicklook_" + std::to_string(::getpid()));
    fs::remove_all(root);
    fs::create_directories(root / "camera");
    fs::create_directories(root / "out");
    test::WriteVideoDataset(root / "model", {0, 1, 2, 3}, test::VideoPsfs(), nullptr);
  }
  ~LiveDirs() {
    std::error_code ec;
    fs::remove_all(root, ec);
  }
  std::string Camera(const std::string& name = "") const { return (root / "camera" / name).string(); }
};

struct Written {
  std::string name;
  std::string status;  // expected
  int j = -1, phase = -1;
  double t = 0;
};

// The camera's night: 4 phases cycled at 50 frames/s, with the mishaps a quick-look must survive.
std::vector<Written> Night() {
  std::vector<Written> w;
  for (int j = 0; j < 14; ++j) {
    if (j == 11) continue;  // phase 3 of the third cycle is lost: its older frame (7) stays in use
    w.push_back({"f" + std::to_string(100 + j) + ".fits", "used", j, j % 4, 0.02 * j});
  }
  // Out of order: a phase-2 frame from before the current one of that phase arrives after frame 13.
  w.push_back({"f099_late.fits", "late", 2, 2, 0.02 * 2});
  w.push_back({"f114.fits", "used", 14, 2, 0.02 * 14});
  return w;
}

TEST(QuickLook, EveryFileIsAccountedForAndOutputsEqualTheEngineFedDirectly) {
  LiveDirs dirs;
  const Dataset model = LoadDataset((dirs.root / "model").string());
  QuickLookOptions o;
  o.video.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  o.video.reconstruct.tikhonov.lambda = 3e-3;
  o.time_key = "TSEC";
  o.output_dir = (dirs.root / "out").string();
  o.watch.poll_interval_s = 0.05;
  o.watch.abandon_after_s = 0.4;
  QuickLook ql(dirs.Camera(), model, o);
  const std::vector<Written> night = Night();
  test::JoiningThread camera([&] {
    for (const Written& f : night) {
      if (f.j == 5) {  // written in place, in two parts, 30 ms apart
        test::WriteLiveFrameInTwoParts(dirs.Camera(f.name), (dirs.root / "staging.fits").string(), f.j, f.phase, f.t, 0.03);
      } else {
        test::WriteLiveFrame(dirs.Camera(f.name), f.j, f.phase, f.t);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    FitsHeader h;
    h.Set("DMPHASE", 1);
    WriteFits(dirs.Camera("wrong_shape.fits"), Image::Zero(5, 5), h);
    WriteFits(dirs.Camera("no_phase.fits"), Image::Zero(24, 20));
    h.Set("DMPHASE", 7);
    WriteFits(dirs.Camera("phase_7.fits"), Image::Zero(24, 20), h);
    std::ofstream(dirs.Camera("stuck.fits"), std::ios::binary) << std::string(2880, ' ');  // never finished
  });
  std::map<std::string, QuickLookEvent> events;
  const std::size_t expected = night.size() + 4;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (events.size() < expected && std::chrono::steady_clock::now() < deadline) {
    std::optional<QuickLookEvent> e = ql.Next(0.5);
    if (!e) continue;
    const std::string name = fs::path(e->file).filename().string();
    EXPECT_EQ(events.count(name), 0u) << name << " reported twice";
    events[name] = *e;
  }
  camera.Join();
  EXPECT_FALSE(ql.Next(0.3)) << "an event beyond the files written";
  ASSERT_EQ(events.size(), expected);
  EXPECT_EQ(events["wrong_shape.fits"].status, "rejected");
  EXPECT_THAT(events["wrong_shape.fits"].message, HasSubstr("shape"));
  EXPECT_THAT(events["no_phase.fits"].message, HasSubstr("no DMPHASE"));
  EXPECT_THAT(events["phase_7.fits"].message, HasSubstr("phases 0..3"));
  EXPECT_EQ(events["stuck.fits"].status, "incomplete");
  EXPECT_EQ(ql.rejected(), 3);
  EXPECT_EQ(ql.incomplete(), 1);
  EXPECT_EQ(ql.late(), 1);
  EXPECT_EQ(ql.used(), int(night.size()) - 1);

  // The reference: the streaming engine fed the used frames, in the order the quick-look used them.
  DatasetVideo reference(model, o.video, o.problem);
  std::vector<const QuickLookEvent*> used(std::size_t(ql.used()), nullptr);
  for (const Written& f : night) {
    const QuickLookEvent& e = events[f.name];
    EXPECT_EQ(e.status, f.status) << f.name << ": " << e.message;
    if (e.status != "used") continue;
    EXPECT_EQ(e.slot, f.phase);
    EXPECT_DOUBLE_EQ(e.time_s, f.t);
    ASSERT_GE(e.frame, 0);
    used[std::size_t(e.frame)] = &e;
  }
  int outputs = 0;
  Image last;
  for (const QuickLookEvent* e : used) {
    ASSERT_NE(e, nullptr);
    int j = -1;
    for (const Written& f : night)
      if (events[f.name].frame == e->frame && f.status == "used") j = f.j;
    const std::optional<VideoFrame> ref =
        reference.PushFrame(e->slot, e->frame, e->time_s, Image(test::VideoFrameE(j) / test::kVideoGain + test::kVideoBias));
    ASSERT_EQ(ref.has_value(), e->output.has_value()) << "frame " << e->frame;
    if (!ref) continue;
    ++outputs;
    EXPECT_TRUE((ref->image == e->output->image).all()) << "output " << ref->index;
    EXPECT_EQ(ref->frames, e->output->frames);
    if (e->written_output >= 0) { EXPECT_GT(e->latency_s, 0.0); }
    last = ref->image;
  }
  // Sliding window: an output for every used frame from the 4th on.
  EXPECT_EQ(outputs, ql.used() - 3);
  EXPECT_EQ(ql.outputs(), outputs);
  // Every output is written unless a newer file was already waiting; the last one always is.
  int written = 0;
  for (const auto& [name, e] : events) written += e.written_output >= 0;
  EXPECT_EQ(written + ql.superseded(), outputs);
  // After the lost frame 11, phase 3 is still frame 7's (frame number 7 among the used frames).
  const QuickLookEvent& after = events["f112.fits"];
  ASSERT_TRUE(after.output);
  EXPECT_EQ(after.output->frames[3], 7);

  const FitsData ql_file = ReadFits((dirs.root / "out" / "quicklook.fits").string());
  ASSERT_EQ(ql_file.planes.size(), 1u);
  EXPECT_LT((ql_file.planes[0] - last).abs().maxCoeff(), 1e-6 * last.abs().maxCoeff());
  EXPECT_EQ(ql_file.header.GetInt("QLOUTPUT"), outputs - 1);
  EXPECT_EQ(ql_file.header.GetString("CTYPE1"), "RA---TAN");
  EXPECT_EQ(ql_file.header.GetString("QLFILE2"), "f114.fits");
  EXPECT_TRUE(fs::exists(dirs.root / "out" / "quicklook.png"));
}

TEST(QuickLook, BadOptionsAndFoldersAreNamed) {
  LiveDirs dirs;
  const Dataset model = LoadDataset((dirs.root / "model").string());
  QuickLookOptions o;
  o.phase_key = "dm phase";
  EXPECT_THAT(test::ErrorOf([&] { QuickLook q(dirs.Camera(), model, o); }), HasSubstr("phase_key"));
  o = {};
  o.time_key = "TOOLONGKEY";
  EXPECT_THAT(test::ErrorOf([&] { QuickLook q(dirs.Camera(), model, o); }), HasSubstr("time_key"));
  o = {};
  o.output_dir = (dirs.root / "absent").string();
  EXPECT_THAT(test::ErrorOf<IoError>([&] { QuickLook q(dirs.Camera(), model, o); }), HasSubstr("absent"));
  o = {};
  EXPECT_THAT(test::ErrorOf<IoError>([&] { QuickLook q(dirs.Camera("nope"), model, o); }), HasSubstr("nope"));
  o.problem.stars_psfs = true;
  EXPECT_THAT(test::ErrorOf([&] { QuickLook q(dirs.Camera(), model, o); }), HasSubstr("stars_psfs"));
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
