// exp_neg (src/core/exp_neg.h), the vectorizable e^{-tau} of the LPM segments and the forward
// peak's empty cells, against std::exp.
#include "src/core/exp_neg.h"

#include <gtest/gtest.h>

#include <cmath>

namespace nimbus {
namespace {

// Relative error below 3e-15 over [0, 700] (dense near 0, where the reduction's n is 0 and the
// series alone works, and across many binades); exactly 1 at 0; clamped beyond 700, positive.
TEST(ExpNeg, WithinThreeEMinusFifteenOfStdExp) {
    double worst = 0.0;
    for (int q = 0; q <= 200000; ++q) {
        const double tau = 700.0 * std::pow(q / 200000.0, 3.0);
        worst = std::max(worst, std::abs(exp_neg(tau) / std::exp(-tau) - 1.0));
    }
    for (double tau : {1e-300, 1e-12, 0.34657359027997264, 0.6931471805599453, 1.0,
                       36.04365338911715, 699.999}) {
        worst = std::max(worst, std::abs(exp_neg(tau) / std::exp(-tau) - 1.0));
    }
    EXPECT_LT(worst, 3e-15);
    EXPECT_EQ(exp_neg(0.0), 1.0);
    EXPECT_EQ(exp_neg(1e6), exp_neg(700.0));
    EXPECT_GT(exp_neg(1e6), 0.0);
    EXPECT_TRUE(std::isnormal(exp_neg(1e300)));
}

}  // namespace
}  // namespace nimbus
