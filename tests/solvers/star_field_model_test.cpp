// The stars' frame model that EstimateStarsPsf fits (solvers/star_field_model.hpp), over one PSF and over the
// nodes of a field grid: its adjoint (the fit's normal equations are built from it), and the field interpolation
// it applies (each star seen through the PSF interpolated at its position, core/psf_field.hpp).
#include "solvers/star_field_model.hpp"  // the library's solvers/ folder (tests/CMakeLists.txt)

#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <vector>

#include "aosr/core/adjoint_test.hpp"
#include "aosr/core/linear_operator.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using stars_internal::Star;
using stars_internal::StarFieldModel;

constexpr int kR = 2;
constexpr Index kK = 9;  // PSF side, HR px
const Shape kHr{40, 48};

Shape Pad() { return {NextFastFftSize(kHr.rows + kK), NextFastFftSize(kHr.cols + kK)}; }

std::vector<Star> RandomStars(int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> py(0.0, kHr.rows - 1.0), px(0.0, kHr.cols - 1.0), flux(50.0, 500.0);
  std::vector<Star> stars(count);
  for (Star& s : stars) {
    s.y = py(rng);
    s.x = px(rng);
    s.f = flux(rng);
  }
  return stars;
}

std::vector<FrameOffset> Offsets() { return {{0.0, 0.0}, {0.0, 1.0}, {1.0, 0.0}, {1.0, 1.0}}; }

// u = [h_0 .. h_{G-1}; b] -> the N frames stacked (camera px), for the adjoint test.
class StarFieldOperator final : public LinearOperator {
 public:
  StarFieldOperator(StarFieldModel* m, Index lr_pixels)
      : LinearOperator(m->frames() * lr_pixels, m->unknowns_psf() + m->frames(), "StarFieldOperator"),
        m_(m),
        lr_pixels_(lr_pixels) {}

 private:
  void ApplyImpl(ConstRef u, Ref y) const override {
    const Index gk2 = m_->unknowns_psf();
    for (Index i = 0; i < m_->frames(); ++i) {
      const Image f = m_->Render(u.head(gk2), i) + u(gk2 + i);
      y.segment(i * lr_pixels_, lr_pixels_) = Eigen::Map<const Vector>(f.data(), lr_pixels_);
    }
  }
  void ApplyAdjointImpl(ConstRef y, Ref u) const override {
    const Shape lr = m_->lr();
    ImageStack c;
    for (Index i = 0; i < m_->frames(); ++i)
      c.push_back(Eigen::Map<const Image>(y.data() + i * lr_pixels_, lr.rows, lr.cols));
    m_->Backward(c, u);
  }
  StarFieldModel* m_;
  Index lr_pixels_;
};

TEST(StarFieldModelTest, AdjointOnOnePsfAndOnAFieldGrid) {
  const std::vector<Star> stars = RandomStars(12, 7);
  for (int nodes : {1, 2, 3}) {
    const PsfFieldGrid grid = nodes == 1 ? PsfFieldGrid() : PsfFieldGrid(kHr, nodes, nodes);
    StarFieldModel m(stars, grid, Offsets(), Pad(), kHr, kR, kK);
    const Shape lr = m.lr();
    const StarFieldOperator op(&m, lr.rows * lr.cols);
    const AdjointTestResult r = AdjointTest(op, 3);
    EXPECT_LT(r.adjoint_error, 1e-10) << nodes << " x " << nodes << " nodes";
  }
}

// Normal(u, w) is Aᵀ W A u: against the backward projection of the weighted forward model, for random weights.
TEST(StarFieldModelTest, NormalIsTheWeightedBackwardOfTheForward) {
  const std::vector<Star> stars = RandomStars(10, 11);
  StarFieldModel m(stars, PsfFieldGrid(kHr, 2, 3), Offsets(), Pad(), kHr, kR, kK);
  const Shape lr = m.lr();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uw(0.2, 2.0);
  ImageStack w;
  for (Index i = 0; i < m.frames(); ++i) {
    Image wi(lr.rows, lr.cols);
    for (Index k = 0; k < wi.size(); ++k) wi.data()[k] = uw(rng);
    w.push_back(wi);
  }
  const Vector u = Vector::Random(m.unknowns_psf() + m.frames());
  Vector z(u.size()), expected(u.size());
  m.Normal(u, w, z);
  ImageStack c;
  for (Index i = 0; i < m.frames(); ++i)
    c.push_back((m.Render(u.head(m.unknowns_psf()), i) + u(m.unknowns_psf() + i)) * w[std::size_t(i)]);
  m.Backward(c, expected);
  EXPECT_LT((z - expected).norm(), 1e-12 * expected.norm());
}

// The bilinear weights of each star sum to one, so the same PSF at every node is the one-PSF model.
TEST(StarFieldModelTest, TheSamePsfAtEveryNodeIsOnePsf) {
  const std::vector<Star> stars = RandomStars(15, 13);
  const Vector h = Vector::Random(kK * kK).cwiseAbs();
  StarFieldModel one(stars, PsfFieldGrid(), Offsets(), Pad(), kHr, kR, kK);
  for (int nodes : {2, 4}) {
    StarFieldModel field(stars, PsfFieldGrid(kHr, nodes, nodes), Offsets(), Pad(), kHr, kR, kK);
    const Vector hg = h.replicate(nodes * nodes, 1);
    for (Index i = 0; i < one.frames(); ++i) {
      const Image a = one.Render(h, i), b = field.Render(hg, i);
      EXPECT_LT((a - b).abs().maxCoeff(), 1e-11 * (a).abs().maxCoeff()) << nodes << " x " << nodes << ", frame " << i;
    }
  }
}

// A star on a node sees that node's PSF alone; a star halfway between two nodes sees their mean.
TEST(StarFieldModelTest, AStarSeesThePsfInterpolatedAtItsPosition) {
  const PsfFieldGrid grid(kHr, 2, 3);
  const Index k2 = kK * kK;
  Vector h(grid.nodes() * k2);
  for (int g = 0; g < grid.nodes(); ++g) h.segment(g * k2, k2) = Vector::Random(k2).cwiseAbs();
  const std::array<double, 2> n0 = grid.Node(0), n1 = grid.Node(1), n4 = grid.Node(4);
  struct Case {
    double y, x;
    Vector psf;  // the PSF the star should see
  };
  const std::vector<Case> cases = {
      {n4[0], n4[1], h.segment(4 * k2, k2)},
      {n0[0], 0.5 * (n0[1] + n1[1]), 0.5 * (h.segment(0, k2) + h.segment(k2, k2))},
  };
  for (const Case& c : cases) {
    Star s;
    s.y = c.y;
    s.x = c.x;
    s.f = 100.0;
    StarFieldModel field({s}, grid, Offsets(), Pad(), kHr, kR, kK);
    StarFieldModel one({s}, PsfFieldGrid(), Offsets(), Pad(), kHr, kR, kK);
    for (Index i = 0; i < field.frames(); ++i) {
      const Image a = field.Render(h, i), b = one.Render(c.psf, i);
      EXPECT_LT((a - b).abs().maxCoeff(), 1e-11 * (b).abs().maxCoeff()) << "star at (" << c.y << ", " << c.x << "), frame " << i;
    }
  }
}

}  // namespace AOSR_TEST_NS
}  // namespace aosr
