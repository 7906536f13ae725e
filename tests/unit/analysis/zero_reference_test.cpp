// `nimbus compare` against a reference that is zero where it is compared (src/analysis/
// compare.h): a relative error is then undefined, NaN with the reason, never infinite, and the
// absolute difference is still given. Equal fields agree exactly (every metric 0), also when
// both are zero. No cells with density, a reference standard error of zero and a black
// reference image are undefined the same way.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "src/analysis/compare.h"

namespace nimbus {
namespace {

TEST(ZeroReference, RelativeErrorsAreUndefinedWithTheReason) {
    const std::vector<double> zero{0.0, 0.0, 0.0}, a{3.0, 0.0, -4.0}, rho{1.0, 1.0, 1.0},
        s{0.0, 0.0, 0.0};
    const FieldError e = field_error(a, zero, rho, &s);
    EXPECT_TRUE(std::isnan(e.rel_l2));
    EXPECT_TRUE(std::isnan(e.max_rel));
    EXPECT_TRUE(std::isnan(e.rms_z));  // a Monte Carlo reference of zero has a zero standard error
    EXPECT_EQ(e.undefined, "the reference is zero on every cell compared");
    EXPECT_EQ(e.cells, 3u);
    EXPECT_DOUBLE_EQ(e.abs_l2, 5.0);  // ||(3, 0, -4)||
    EXPECT_DOUBLE_EQ(e.max_abs, 4.0);
    EXPECT_EQ(e.norm_b, 0.0);

    // Zero on the cells compared (the empty cell's 7 does not count); without a standard error
    // RMS z stays "not given".
    const FieldError f = field_error({1.0, 2.0}, {0.0, 7.0}, {1.0, 0.0}, nullptr);
    EXPECT_TRUE(std::isnan(f.rel_l2));
    EXPECT_TRUE(std::isnan(f.max_rel));
    EXPECT_EQ(f.rms_z, -1.0);
    EXPECT_EQ(f.undefined, "the reference is zero on every cell compared");
    EXPECT_DOUBLE_EQ(f.abs_l2, 1.0);
}

TEST(ZeroReference, EqualFieldsAgreeExactlyAlsoWhenZero) {
    const std::vector<double> zero{0.0, 0.0}, rho{1.0, 1.0};
    const FieldError e = field_error(zero, zero, rho, &zero);
    EXPECT_EQ(e.rel_l2, 0.0);
    EXPECT_EQ(e.max_rel, 0.0);
    EXPECT_EQ(e.rms_z, 0.0);
    EXPECT_EQ(e.abs_l2, 0.0);
    EXPECT_TRUE(e.undefined.empty());
    // A non-zero reference: defined as always.
    const FieldError g = field_error({1.0, 3.0}, {1.0, 2.0}, rho, nullptr);
    EXPECT_DOUBLE_EQ(g.rel_l2, 1.0 / std::sqrt(5.0));
    EXPECT_DOUBLE_EQ(g.max_rel, 0.5);
    EXPECT_TRUE(g.undefined.empty());
}

TEST(ZeroReference, NoCellsWithDensityOrNoStandardError) {
    const std::vector<double> a{1.0, 2.0}, b{2.0, 2.0}, s{0.0, 0.0};
    const FieldError none = field_error(a, b, {0.0, 0.0}, &s);
    EXPECT_EQ(none.cells, 0u);
    EXPECT_TRUE(std::isnan(none.rel_l2));
    EXPECT_TRUE(std::isnan(none.max_rel));
    EXPECT_TRUE(std::isnan(none.rms_z));
    EXPECT_EQ(none.undefined, "no cells with density");

    // The reference is not zero but has no standard error anywhere: only RMS z is undefined.
    const FieldError e = field_error(a, b, {1.0, 1.0}, &s);
    EXPECT_DOUBLE_EQ(e.rel_l2, 1.0 / std::sqrt(8.0));
    EXPECT_DOUBLE_EQ(e.max_rel, 0.5);
    EXPECT_TRUE(std::isnan(e.rms_z));
    EXPECT_EQ(e.undefined, "no cell compared has a usable standard error (above 0, below half the value)");
}

TEST(ZeroReference, BlackReferenceImage) {
    const std::vector<float> black{0, 0, 0, 1, 0, 0, 0, 1}, a{0, 3, 0, 1, 0, 0, 0, 0};
    const ImageError e = image_error(a, black);
    EXPECT_TRUE(std::isnan(e.rel_error));
    EXPECT_EQ(e.undefined, "the reference image is black");
    EXPECT_DOUBLE_EQ(e.rmse, std::sqrt(9.0 / 6.0));  // alpha ignored
    const ImageError same = image_error(black, black);
    EXPECT_EQ(same.rel_error, 0.0);
    EXPECT_TRUE(same.undefined.empty());
}

}  // namespace
}  // namespace nimbus
