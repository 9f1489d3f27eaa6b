// Issue 33's target: the slanted-edge MTF of a noise-free Tikhonov or target-PSF (linear) reconstruction of an
// edge scene matches the exact transfer (solvers/linear_transfer.hpp) within 0.03 up to the HR Nyquist.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "aosr/core/slanted_edge.hpp"
#include "aosr/scene/objects.hpp"
#include "aosr/solvers/linear_transfer.hpp"
#include "aosr/solvers/target_psf.hpp"
#include "aosr/solvers/tikhonov.hpp"
#include "solvers/tikhonov_fixture.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

// Issue 33's target is 0.03; measured here (noise-free, 192 rows): <= 0.0015 for Tikhonov, <= 0.0005 for the
// target-PSF output. The test holds the tighter bound so that a regression well inside the target still shows.
constexpr double kLinTransferTolerance = 0.005;

struct EdgeCase {
  int r;
  std::vector<std::pair<double, double>> shifts;  // HR px
  double sigma;                                   // PSF width, HR px
  double angle_deg;
};

// A 256² HR edge scene (low 0.1, high 1), its noise-free frames and the problem; the edge read in the central
// ROI, 64 px from the wrap-around's edges.
struct EdgeScene {
  Shape hr{256, 256};
  std::shared_ptr<const MultiFrameModel> model;
  ReconstructionProblem problem;
  SlantedEdgeOptions edge;
  explicit EdgeScene(const EdgeCase& c) {
    model = std::make_shared<MultiFrameModel>(test::RasterModel(hr, c.r, c.shifts, c.sigma));
    SlantedEdgeTargetOptions t;
    t.angle_deg = c.angle_deg;
    t.low = 0.1;
    t.high = 1.0;
    const Image truth = SlantedEdgeTarget(hr, t);
    problem.model = model;
    problem.frames = model->Render(truth);
    edge.roi = {64, 32, 128, 192};
    edge.curve_max = 0.5;
    // The ESF's tail smoothing (core/slanted_edge.hpp, for noisy edges) assumes a monotone tail; a reconstruction's
    // LSF rings (Tikhonov's T falls steeply near the cut-off), and smoothing its tails moved these curves by up to
    // 0.16. The frames are noise-free: read the plain ISO 12233 estimate.
    edge.smooth_tails = false;
  }
};

// max |measured − exact| over f <= 0.5 cycles/HR px, the exact curve along the measured edge's normal.
double WorstGap(const SlantedEdgeMtf& m, const TransferCurve& exact) {
  double worst = 0;
  for (std::size_t i = 0; i < m.frequency.size(); ++i)
    if (m.frequency[i] <= 0.5 + 1e-12) worst = std::max(worst, std::abs(m.mtf[i] - exact.mtf[i]));
  return worst;
}

TransferCurveOptions AlongEdge(const SlantedEdgeMtf& m) {
  TransferCurveOptions o;
  SetDirectionFromEdge(m, &o);
  o.frequencies = m.frequency;
  return o;
}

const std::vector<EdgeCase>& Cases() {
  static const std::vector<EdgeCase> cases = {
      {2, {{0, 0}, {0, 1}, {1, 0}, {1, 1}}, 1.2, 5.0},     // the half-pixel raster, N = r²
      {2, {{0, 0}, {1, 1}}, 1.0, -7.0},                    // N < r²: aliasing the prior must fill
      {4, {{0, 0}, {0, 2}, {2, 0}, {2, 2}}, 2.0, 4.0},     // r = 4 with 4 frames
  };
  return cases;
}

TEST(LinearTransferPhysicsTest, TikhonovEdgeMtfMatchesTheExactTransfer) {
  for (const EdgeCase& c : Cases())
    for (double lambda : {1e-3, 3e-2}) {
      const EdgeScene s(c);
      TikhonovOptions o;
      o.lambda = lambda;
      const TikhonovResult rec = ReconstructTikhonov(s.problem, o);
      const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(rec.image, s.edge);
      bool exact = false;
      const TransferCurve t = TikhonovTransferCurve(s.problem, o, lambda, AlongEdge(m), &exact);
      EXPECT_TRUE(exact);
      const double gap = WorstGap(m, t);
      EXPECT_LT(gap, kLinTransferTolerance) << "r=" << c.r << " N=" << c.shifts.size() << " lambda=" << lambda
                                            << " edge " << c.angle_deg << " deg";
      // The curve is not trivially flat: the reconstruction loses contrast at the HR Nyquist.
      EXPECT_LT(t.mtf.back(), 0.9);
      std::printf("tikhonov r=%d N=%zu lambda=%g: worst |edge - exact| %.4f (exact at 0.5: %.3f, alias %.3f)\n", c.r,
                  c.shifts.size(), lambda, gap, t.mtf.back(), t.alias.back());
    }
}

TEST(LinearTransferPhysicsTest, TargetPsfEdgeMtfMatchesItsEffectiveOtf) {
  for (const EdgeCase& c : Cases()) {
    const EdgeScene s(c);
    TargetPsfOptions o;
    o.compute_noise = false;
    const TargetPsfResult rec = ReconstructTargetPsf(s.problem, o);
    const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(rec.image, s.edge);
    const TransferCurve t = KernelTransferCurve(rec.effective_psf, AlongEdge(m));
    const double gap = WorstGap(m, t);
    EXPECT_LT(gap, kLinTransferTolerance) << "r=" << c.r << " N=" << c.shifts.size();
    std::printf("linear r=%d N=%zu: worst |edge - exact| %.4f (exact at 0.25: %.3f)\n", c.r, c.shifts.size(), gap,
                t.mtf[25]);
  }
}

// The test can fail: the exact curve of another λ (30x) or the curve without the HR pixel box is off by more than
// the 0.03 somewhere below the HR Nyquist.
TEST(LinearTransferPhysicsTest, AWrongModelOfTheTransferIsDetected) {
  const EdgeScene s(Cases()[0]);
  TikhonovOptions o;
  o.lambda = 1e-3;
  const SlantedEdgeMtf m = MeasureSlantedEdgeMtf(ReconstructTikhonov(s.problem, o).image, s.edge);
  EXPECT_GT(WorstGap(m, TikhonovTransferCurve(s.problem, o, 3e-2, AlongEdge(m))), 0.03);
  TransferCurveOptions no_box = AlongEdge(m);
  no_box.hr_pixel_box = false;
  EXPECT_GT(WorstGap(m, TikhonovTransferCurve(s.problem, o, 1e-3, no_box)), 0.03);
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
