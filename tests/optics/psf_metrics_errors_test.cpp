#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>

#include "aosr/optics/psf_metrics.hpp"
#include "support/testing.hpp"

namespace aosr {
namespace AOSR_TEST_NS {

using aosr::test::ErrorOf;
using ::testing::HasSubstr;

TEST(PsfMetricsErrorsTest, BadImagesAndRadiiAreRejected) {
  EXPECT_THAT(ErrorOf([] { MeasurePsf(Image()); }), HasSubstr("empty"));
  Image nan = Image::Ones(4, 4);
  nan(1, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { MeasurePsf(nan); }), HasSubstr("non-finite"));
  EXPECT_THAT(ErrorOf([] { EncircledEnergy(Image::Zero(4, 4), {1.0}); }), HasSubstr("psf sum"));
  EXPECT_THAT(ErrorOf([] { EncircledEnergy(Image::Ones(4, 4), {-1.0}); }), HasSubstr("radius"));
  EXPECT_THAT(ErrorOf([] { CoreCentroid(Image::Ones(4, 4), 0.2); }), HasSubstr("CoreCentroid: invalid radius_px"));
  EXPECT_THAT(ErrorOf([&] { CoreCentroid(nan, 2.0); }), HasSubstr("non-finite"));
}

}  // namespace
}  // namespace aosr
