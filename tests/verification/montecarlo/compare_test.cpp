// The error metrics of `nimbus compare` (src/analysis/compare.h) on hand-computed cases.
#include <gtest/gtest.h>

#include <cmath>

#include "src/analysis/compare.h"
#include "src/core/error.h"

namespace nimbus {
namespace {

TEST(Compare, FieldMetricsOverCellsWithDensity) {
    const std::vector<double> b{1.0, 2.0, 2.0, 100.0}, a{1.0, 3.0, 1.0, -5.0};
    const std::vector<double> rho{1.0, 0.5, 2.0, 0.0};  // the last cell is empty: ignored
    const FieldError e = field_error(a, b, rho, nullptr);
    EXPECT_EQ(e.cells, 3u);
    EXPECT_DOUBLE_EQ(e.rel_l2, std::sqrt(2.0) / 3.0);  // ||(0, 1, -1)|| / ||(1, 2, 2)||
    EXPECT_DOUBLE_EQ(e.max_rel, 0.5);                  // max |d| = 1, max |b| = 2
    EXPECT_EQ(e.rms_z, -1.0);
}

TEST(Compare, RmsZUsesTheReferenceStandardError) {
    const std::vector<double> b{1.0, 2.0, 3.0}, a{1.25, 1.0, 3.0}, rho{1, 1, 1}, s{0.25, 0.5, 0.0};
    const FieldError e = field_error(a, b, rho, &s);
    EXPECT_DOUBLE_EQ(e.rms_z, std::sqrt((1.0 + 4.0) / 2.0));  // z = 1, -2; the s = 0 cell skipped
    EXPECT_EQ(e.cells, 3u);
    EXPECT_EQ(e.z_cells, 2u);  // and counted apart, so that compare can say so
}

TEST(Compare, RmsZLeavesOutCellsWhoseStandardErrorIsHalfTheirValue) {
    // Cell 2: s = 0.5 b, a few batches' estimate, left out; cell 3 just below the cut.
    const std::vector<double> b{1.0, 2.0, 1.0}, a{1.5, 0.0, 2.0}, rho{1, 1, 1}, s{0.25, 1.0, 0.49};
    const FieldError e = field_error(a, b, rho, &s);
    EXPECT_EQ(e.z_cells, 2u);
    EXPECT_DOUBLE_EQ(e.rms_z, std::sqrt((4.0 + 1.0 / (0.49 * 0.49)) / 2.0));  // z = 2, 1 / 0.49
}

TEST(Compare, RmsZOfTwoMonteCarloRunsCountsBothStandardErrors) {
    const std::vector<double> b{1.0, 2.0, 4.0}, a{1.5, 2.0, 3.0}, rho{1, 1, 1};
    const std::vector<double> sb{0.3, 0.1, 0.5}, sa{0.4, 0.1, 2.0};  // A's cell 3: s = 2/3 of a
    const FieldError e = field_error(a, b, rho, &sb, &sa);
    EXPECT_EQ(e.z_cells, 2u);
    EXPECT_DOUBLE_EQ(e.rms_z, std::sqrt((0.25 / 0.25 + 0.0) / 2.0));  // s² = 0.3² + 0.4² = 0.25
    // Without B's standard error there is no z, whatever A has.
    EXPECT_EQ(field_error(a, b, rho, nullptr, &sa).rms_z, -1.0);
}

// (A zero reference, undefined metrics: tests/unit/analysis/zero_reference_test.cpp.)
TEST(Compare, SizeMismatch) {
    const std::vector<double> z{0.0, 0.0}, rho{1, 1}, s1{1.0};
    EXPECT_THROW(field_error({1.0}, z, rho, nullptr), Error);
    EXPECT_THROW(field_error(z, z, {1.0}, nullptr), Error);
    EXPECT_THROW(field_error(z, z, rho, &s1), Error);
}

TEST(Compare, ImageMetricsIgnoreAlpha) {
    const std::vector<float> b{1, 2, 2, 1, 0, 0, 0, 0}, a{1, 2, 4, 0, 0, 0, 1, 0};
    const ImageError e = image_error(a, b);
    EXPECT_EQ(e.pixels, 2u);
    EXPECT_DOUBLE_EQ(e.rmse, std::sqrt(5.0 / 6.0));  // differences (0, 0, 2), (0, 0, 1)
    EXPECT_DOUBLE_EQ(e.rel_error, std::sqrt(5.0) / 3.0);
    EXPECT_THROW(image_error(a, {1, 2, 3, 4}), Error);
}

}  // namespace
}  // namespace nimbus
