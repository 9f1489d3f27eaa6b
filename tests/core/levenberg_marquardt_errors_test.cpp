#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aosr/core/error.hpp"
#include "aosr/core/levenberg_marquardt.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

TEST(LevenbergMarquardtErrorsTest, NegativeOptionsAreRejectedNamingTheField) {
  const LeastSquaresResiduals r = [](const Eigen::VectorXd& th, Eigen::MatrixXd* jac) {
    if (jac) *jac = Eigen::MatrixXd::Identity(1, 1);
    return Eigen::VectorXd(th);
  };
  LevenbergMarquardtOptions o;
  o.max_iterations = -1;
  EXPECT_THAT([&] { LevenbergMarquardt(r, Eigen::VectorXd::Ones(1), nullptr, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("max_iterations")));
  o = LevenbergMarquardtOptions{};
  o.tolerance = -1e-3;
  EXPECT_THAT([&] { LevenbergMarquardt(r, Eigen::VectorXd::Ones(1), nullptr, o); },
              ::testing::ThrowsMessage<InvalidArgument>(::testing::HasSubstr("tolerance")));
}

}  // namespace
}  // namespace aosr
