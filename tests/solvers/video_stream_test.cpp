// Streaming super-resolution (video_stream.hpp): every slot-filter output against the batch Reconstruct of the
// same window, built independently (frames in time order, the model's PSFs permuted to match), to 1e-10 of the
// peak for Tikhonov (fixed and once-chosen λ) and the target-PSF output, sliding and cycle windows; the weighted
// fallback; thread-count independence; warm-started TV approaching TV to convergence; a sequence dataset on disk.
#include "aosr/solvers/video_stream.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "aosr/core/error.hpp"
#include "aosr/core/fft.hpp"
#include "aosr/core/parallel.hpp"
#include "aosr/io/fits.hpp"
#include "solvers/tikhonov_fixture.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using test::RasterModel;

const std::vector<std::pair<double, double>> kShifts = {{0, 0}, {0, 1}, {1, 0}, {1, 1.5}};
constexpr Shape kHr{48, 40};
constexpr int kR = 2;

std::shared_ptr<const MultiFrameModel> SlotModel(const std::vector<int>& order = {0, 1, 2, 3}) {
  std::vector<std::pair<double, double>> s;
  for (int i : order) s.push_back(kShifts[std::size_t(i)]);
  return std::make_shared<MultiFrameModel>(RasterModel(kHr, kR, s, 1.1));
}

// A blob moving one HR pixel per frame over a random background: every window differs.
Image Object(int frame) {
  Image x = 0.1 * test::RandomImage(kHr, 11, false);
  for (Index y = 0; y < kHr.rows; ++y)
    for (Index c = 0; c < kHr.cols; ++c) {
      const double dy = double(y) - 20.0, dx = double(c) - 10.0 - frame;
      x(y, c) += 3.0 * std::exp(-(dy * dy + dx * dx) / 8.0);
    }
  return x;
}

// Frame j of the stream: slot j mod 4 of the object at time j, with noise.
Image StreamFrame(int j) {
  const auto model = SlotModel();
  Image f = model->Render(Object(j))[std::size_t(j % 4)];
  return f + 0.01 * test::RandomImage(model->lr_shape(), 100 + std::uint64_t(j));
}

double Peak(const Image& x) { return x.abs().maxCoeff(); }

// The batch reconstruction of input frames `frames` (indices, any order), built without the engine: the frames
// in the order given and a model whose frame k is the slot of frames[k].
Image IndependentBatch(const std::vector<int>& frames, const ReconstructOptions& o) {
  std::vector<int> order;
  ReconstructionProblem p;
  for (int j : frames) {
    order.push_back(j % 4);
    p.frames.push_back(StreamFrame(j));
  }
  p.model = SlotModel(order);
  return Reconstruct(p, o).image;
}

// The input frames of an output in time order.
std::vector<int> TimeOrder(std::vector<int> f) {
  std::sort(f.begin(), f.end());
  return f;
}

void ExpectStreamEqualsBatch(const VideoOptions& vo, int frames, int expected_outputs) {
  VideoReconstructor engine(SlotModel(), vo);
  int outputs = 0;
  for (int j = 0; j < frames; ++j) {
    const std::optional<VideoFrame> out = engine.Push(j % 4, j, 0.1 * j, StreamFrame(j));
    if (!out) continue;
    ++outputs;
    ReconstructOptions batch = engine.BatchOptions(engine.WindowProblem());
    const Image ref = IndependentBatch(TimeOrder(out->frames), batch);
    const double dev = (out->image - ref).abs().maxCoeff() / Peak(ref);
    EXPECT_LT(dev, 1e-10) << "output " << out->index << " (" << out->path << ")";
    EXPECT_DOUBLE_EQ(out->time_s, 0.1 * j);
    if (out->index > 0) {
      EXPECT_EQ(out->path, "slot-filter");
    }
  }
  EXPECT_EQ(outputs, expected_outputs);
  EXPECT_GT(engine.setup().filter_outputs, 0);
}

TEST(VideoStream, TikhonovFixedLambdaSlidingEqualsBatch) {
  VideoOptions vo;
  vo.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  vo.reconstruct.tikhonov.lambda = 3e-3;
  ExpectStreamEqualsBatch(vo, 11, 8);  // an output for frames 3..10
}

TEST(VideoStream, TikhonovLambdaChosenOnceByGcv) {
  VideoOptions vo;  // GCV: on the first window, by the batch
  VideoReconstructor engine(SlotModel(), vo);
  for (int j = 0; j < 7; ++j) {
    const std::optional<VideoFrame> out = engine.Push(j % 4, j, j, StreamFrame(j));
    if (!out) continue;
    if (out->index == 0) {
      EXPECT_EQ(out->path, "batch");
      ReconstructOptions gcv;  // Reconstruct's default: GCV
      const Image ref = IndependentBatch(TimeOrder(out->frames), gcv);
      EXPECT_LT((out->image - ref).abs().maxCoeff() / Peak(ref), 1e-10);
      EXPECT_GT(engine.setup().lambda_unweighted, 0);
    } else {
      EXPECT_EQ(out->path, "slot-filter");
      ReconstructOptions fixed;
      fixed.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
      fixed.tikhonov.lambda = engine.setup().lambda_unweighted;  // unit weights: λ = λ'
      const Image ref = IndependentBatch(TimeOrder(out->frames), fixed);
      EXPECT_LT((out->image - ref).abs().maxCoeff() / Peak(ref), 1e-10) << "output " << out->index;
    }
  }
}

TEST(VideoStream, LinearTargetPsfSlidingEqualsBatch) {
  VideoOptions vo;
  vo.method = ReconstructionMethod::kLinear;
  VideoReconstructor engine(SlotModel(), vo);
  int outputs = 0;
  for (int j = 0; j < 9; ++j) {
    const std::optional<VideoFrame> out = engine.Push(j % 4, j, j, StreamFrame(j));
    if (!out) continue;
    ++outputs;
    EXPECT_EQ(out->path, "slot-filter");
    ReconstructOptions batch;  // the batch's own κ search, not the engine's κ
    batch.method = ReconstructionMethod::kLinear;
    const Image ref = IndependentBatch(TimeOrder(out->frames), batch);
    EXPECT_LT((out->image - ref).abs().maxCoeff() / Peak(ref), 1e-10) << "output " << out->index;
    // And with the κ the stream fixed, which BatchOptions hands on (on larger grids the batch's own search moves
    // with the order of the frames: docs/video.md).
    const ReconstructOptions fixed = engine.BatchOptions(engine.WindowProblem());
    EXPECT_EQ(fixed.linear.kappa, engine.setup().kappa);
    const Image at_kappa = IndependentBatch(TimeOrder(out->frames), fixed);
    EXPECT_LT((out->image - at_kappa).abs().maxCoeff() / Peak(at_kappa), 1e-10) << "output " << out->index;
  }
  EXPECT_EQ(outputs, 6);
  EXPECT_GT(engine.setup().kappa, 0);
}

TEST(VideoStream, CycleWindowOneOutputPerCycle) {
  VideoOptions vo;
  vo.window = VideoWindow::kCycle;
  vo.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  vo.reconstruct.tikhonov.lambda = 1e-2;
  VideoReconstructor engine(SlotModel(), vo);
  std::vector<std::vector<int>> windows;
  for (int j = 0; j < 14; ++j)
    if (const auto out = engine.Push(j % 4, j, j, StreamFrame(j))) {
      windows.push_back(TimeOrder(out->frames));
      const Image ref = IndependentBatch(windows.back(), engine.BatchOptions(engine.WindowProblem()));
      EXPECT_LT((out->image - ref).abs().maxCoeff() / Peak(ref), 1e-10);
    }
  ASSERT_EQ(windows.size(), 3u);
  EXPECT_EQ(windows[1], (std::vector<int>{4, 5, 6, 7}));
  EXPECT_EQ(windows[2], (std::vector<int>{8, 9, 10, 11}));
}

TEST(VideoStream, OutOfOrderAndRepeatedPhasesUseTheLatestFrameOfEachSlot) {
  VideoOptions vo;
  vo.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  vo.reconstruct.tikhonov.lambda = 1e-2;
  VideoReconstructor engine(SlotModel(), vo);
  // Slots 0, 2, 2 (again), 1, 3: the first output uses the second frame of slot 2.
  const std::vector<int> frames = {0, 2, 6, 1, 3};
  std::optional<VideoFrame> out;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    out = engine.Push(frames[k] % 4, frames[k], double(k), StreamFrame(frames[k]));
    if (k + 1 < frames.size()) {
      EXPECT_FALSE(out);
    }
  }
  ASSERT_TRUE(out);
  EXPECT_EQ(out->frames, (std::vector<int>{0, 1, 6, 3}));
}

TEST(VideoStream, WeightedWindowsFallBackToTheWeightedBatch) {
  VideoOptions vo;
  vo.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  vo.reconstruct.tikhonov.lambda = 3e-3;
  VideoReconstructor engine(SlotModel(), vo);
  const Shape lr = SlotModel()->lr_shape();
  int batch = 0, filter = 0;
  for (int j = 0; j < 10; ++j) {
    Image w;
    if (j == 5) {  // one frame with a masked pixel and uneven weights
      w = 1.0 + 0.5 * test::RandomImage(lr, 3, false);
      w(4, 7) = 0;
    }
    const auto out = engine.Push(j % 4, j, j, StreamFrame(j), w);
    if (!out) continue;
    const bool has5 = std::count(out->frames.begin(), out->frames.end(), 5) > 0;
    EXPECT_EQ(out->path, has5 ? "batch" : "slot-filter") << "output " << out->index;
    const ReconstructionProblem window = engine.WindowProblem();
    const Image ref = Reconstruct(window, engine.BatchOptions(window)).image;
    EXPECT_LT((out->image - ref).abs().maxCoeff() / Peak(ref), 1e-10);
    if (has5) {
      ++batch;
      // The filter would be wrong here: the weighted estimate is not the unweighted one.
      ReconstructionProblem unweighted = window;
      unweighted.weights.clear();
      const Image fast = Reconstruct(unweighted, engine.BatchOptions(unweighted)).image;
      EXPECT_GT((fast - ref).abs().maxCoeff() / Peak(ref), 1e-6);
    } else {
      ++filter;
    }
  }
  EXPECT_EQ(batch, 4);  // windows ending at frames 5..8
  EXPECT_EQ(filter, 3);
}

TEST(VideoStream, SameBytesOnOneAndTwoThreads) {
  VideoOptions vo;
  vo.method = ReconstructionMethod::kLinear;
  std::vector<Image> runs[2];
  const int saved = DefaultThreads();
  for (int t = 0; t < 2; ++t) {
    SetDefaultThreads(t + 1);
    VideoReconstructor engine(SlotModel(), vo);
    for (int j = 0; j < 6; ++j)
      if (const auto out = engine.Push(j % 4, j, j, StreamFrame(j))) runs[t].push_back(out->image);
  }
  SetDefaultThreads(saved);
  ASSERT_EQ(runs[0].size(), runs[1].size());
  for (std::size_t k = 0; k < runs[0].size(); ++k)
    EXPECT_EQ(std::memcmp(runs[0][k].data(), runs[1][k].data(), sizeof(double) * std::size_t(runs[0][k].size())), 0);
}

TEST(VideoStream, WarmStartedTvStaysNearTvToConvergence) {
  // A static object: each output runs 5 ADMM iterations from the previous output's ADMM state. It must stay near
  // TV run to convergence on the same window (far nearer than the Tikhonov estimate TV starts from without a
  // warm start), and nearer than the same budget started from the previous x alone (tv_warm_duals = false).
  VideoOptions vo;
  vo.method = ReconstructionMethod::kTotalVariation;
  vo.tv_iterations = 5;
  VideoReconstructor engine(SlotModel(), vo);
  vo.tv_warm_duals = false;
  VideoReconstructor x_only(SlotModel(), vo);
  const auto model = SlotModel();
  const ImageStack clean = model->Render(Object(0));
  int checked = 0;
  double sum_gap = 0, sum_x_only_gap = 0;
  for (int j = 0; j < 16; ++j) {
    const Image f = clean[std::size_t(j % 4)] + 0.01 * test::RandomImage(model->lr_shape(), 500 + std::uint64_t(j % 4));
    const auto out = engine.Push(j % 4, j, j, f);
    const auto out_x = x_only.Push(j % 4, j, j, f);
    ASSERT_EQ(out.has_value(), out_x.has_value());
    if (!out) continue;
    EXPECT_EQ(out->path, out->index == 0 ? "tv" : "tv-warm");
    if (out->index > 0) {
      EXPECT_LE(out->iterations, 5);
    }
    if (out->index <= 1) {  // the first window's batch, then the first warm output (from x alone in both)
      EXPECT_EQ(std::memcmp(out->image.data(), out_x->image.data(), sizeof(double) * std::size_t(out->image.size())), 0);
    }
    if (out->index % 4 != 1) continue;
    ReconstructionProblem w = engine.WindowProblem();
    ReconstructOptions o = engine.BatchOptions(w);
    o.tv.max_iterations = 3000;
    o.tv.relative_tolerance = 1e-7;
    const Image ref = Reconstruct(w, o).image;
    ReconstructOptions t;  // the GCV Tikhonov pilot
    const Image pilot = Reconstruct(w, t).image;
    const double gap = (out->image - ref).matrix().norm() / ref.matrix().norm();
    const double x_only_gap = (out_x->image - ref).matrix().norm() / ref.matrix().norm();
    const double pilot_gap = (pilot - ref).matrix().norm() / ref.matrix().norm();
    EXPECT_LT(gap, 0.25 * pilot_gap) << "output " << out->index;
    EXPECT_LT(gap, 0.02) << "output " << out->index;
    std::printf("output %d: gap %.3e from the state, %.3e from x alone, %.3e the pilot\n", out->index, gap,
                x_only_gap, pilot_gap);
    if (out->index > 1) {
      sum_gap += gap;
      sum_x_only_gap += x_only_gap;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 3);
  EXPECT_LT(sum_gap, 0.6 * sum_x_only_gap);  // measured: 0.38
}

// ---- a sequence dataset on disk -----------------------------------------------------------------------------

struct SequenceDir {
  std::string dir;
  ImageStack psfs;
  explicit SequenceDir(const std::string& name, int frames, bool times) {
    dir = (std::filesystem::temp_directory_path() / ("aosr_video_" + name + "_" + std::to_string(::getpid()))).string();
    std::filesystem::create_directories(dir);
    for (auto [dy, dx] : kShifts) {
      Image k = Image::Zero(16, 16);
      for (Index y = 0; y < 16; ++y)
        for (Index x = 0; x < 16; ++x) {
          const double a = double(y) - 8 - dy, b = double(x) - 8 - dx;
          k(y, x) = std::exp(-(a * a + b * b) / (2 * 1.1 * 1.1));
        }
      psfs.push_back(k / k.sum());
    }
    const auto model = std::make_shared<MultiFrameModel>(MultiFrameModel::FromKernels(kHr, kR, psfs));
    ImageStack adu;
    nlohmann::json slots = nlohmann::json::array(), t = nlohmann::json::array();
    for (int j = 0; j < frames; ++j) {
      const Image e = model->Render(Object(j))[std::size_t(j % 4)] + 0.01 * test::RandomImage(model->lr_shape(), 700 + std::uint64_t(j));
      adu.push_back(e / 2.0 + 100.0);  // gain 2, bias 100
      slots.push_back(j % 4);
      t.push_back(0.05 * j);
    }
    WriteFitsCube(dir + "/frames.fits", adu, {}, FitsType::kFloat64);
    WriteFitsCube(dir + "/psfs.fits", psfs, {}, FitsType::kFloat64);
    nlohmann::json m = {{"format", "aosr-manifest"}, {"version", 1},    {"frames", "frames.fits"},
                        {"psfs", "psfs.fits"},       {"r", kR},         {"gain_e_per_adu", 2.0},
                        {"bias_adu", 100.0}};
    // The detector model as simulations record it: background weights 1/σ², the same for every frame and window.
    m["noise"] = {{"model", "peak-fraction"}, {"sigma_e", 0.01}};
    m["sequence"] = {{"slots", slots}};
    if (times) m["sequence"]["times_s"] = t;
    std::ofstream(dir + "/manifest.json") << m.dump(1);
  }
  ~SequenceDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

TEST(VideoStream, SequenceDatasetLoadsSlotsAndTimes) {
  SequenceDir s("load", 10, true);
  const Dataset d = LoadDataset(s.dir);
  ASSERT_EQ(d.size(), 10);
  EXPECT_EQ(d.slot_count, 4);
  ASSERT_EQ(d.psfs.size(), 10u);
  EXPECT_EQ(d.slots[6], 2);
  EXPECT_TRUE((d.psfs[6] == d.psfs[2]).all());
  EXPECT_DOUBLE_EQ(d.times_s[9], 0.45);
  const Dataset w = SelectFrames(d, {7, 4, 5, 6});
  EXPECT_EQ(w.size(), 4);
  EXPECT_EQ(w.slot_count, 4);
  EXPECT_TRUE((w.psfs[0] == d.psfs[3]).all());
  EXPECT_TRUE((w.frames[1] == d.frames[4]).all());
  EXPECT_DOUBLE_EQ(w.times_s[0], 0.35);
}

TEST(VideoStream, DatasetVideoEqualsBatchOfEachWindowDataset) {
  SequenceDir s("batch", 9, false);
  const Dataset d = LoadDataset(s.dir);
  EXPECT_TRUE(d.times_s.empty());
  VideoOptions vo;
  vo.reconstruct.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
  vo.reconstruct.tikhonov.lambda = 3e-3;
  DatasetVideo video(d, vo, {}, 20.0);
  int outputs = 0;
  while (const auto out = video.Next()) {
    ++outputs;
    EXPECT_DOUBLE_EQ(out->time_s, double(*std::max_element(out->frames.begin(), out->frames.end())) / 20.0);
    // The batch as `aosr reconstruct` would run it on the window's frames as a dataset of their own.
    DatasetProblemOptions po;
    po.method = ReconstructionMethod::kTikhonov;
    const DatasetProblem dp = ProblemFromDataset(SelectFrames(d, TimeOrder(out->frames)), po);
    ReconstructOptions ro;
    ro.tikhonov.lambda_rule = TikhonovLambdaRule::kFixed;
    ro.tikhonov.lambda = 3e-3;
    const Image ref = Reconstruct(dp.problem, ro).image;
    EXPECT_LT((out->image - ref).abs().maxCoeff() / Peak(ref), 1e-10) << "output " << out->index;
  }
  EXPECT_EQ(outputs, 6);
  EXPECT_EQ(video.frames_read(), 9);
}

TEST(VideoStream, OrdinaryDatasetIsOneCycle) {
  SequenceDir s("plain", 4, false);
  nlohmann::json m = nlohmann::json::parse(std::ifstream(s.dir + "/manifest.json"));
  m.erase("sequence");
  std::ofstream(s.dir + "/manifest.json") << m.dump(1);
  const Dataset d = LoadDataset(s.dir);
  EXPECT_EQ(d.slots, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(d.slot_count, 4);
  EXPECT_TRUE(d.times_s.empty());
  VideoOptions vo;
  vo.method = ReconstructionMethod::kLinear;
  DatasetVideo video(d, vo);
  ASSERT_TRUE(video.Next());
  EXPECT_FALSE(video.Next());
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
