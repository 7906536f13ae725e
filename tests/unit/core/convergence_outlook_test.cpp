// convergence_outlook.h: the share of the way to the tolerance and the time left of a
// geometrically converging iteration, from its history of relative changes.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "src/core/convergence_outlook.h"

namespace nimbus {
namespace {

// The progress lines of DOM and the flux limiter come from the history: the way to the tolerance
// on a log scale, and the iterations left at the rate of the last three.
TEST(ConvergenceOutlook, FromTheHistory) {
    auto outlook = [](const std::vector<double>& h) { return convergence_outlook(h, 1e-4); };
    EXPECT_EQ(outlook({}).fraction, 0.0);
    EXPECT_TRUE(std::isnan(outlook({}).remaining_iterations));
    EXPECT_EQ(outlook({1.0}).fraction, 0.0);
    EXPECT_TRUE(std::isnan(outlook({1.0}).remaining_iterations));  // no rate yet
    // Rate 0.1: 1e-2 is half way from 1 to 1e-4 (log scale), 2 more iterations.
    ConvergenceOutlook o = outlook({1.0, 0.1, 1e-2});
    EXPECT_NEAR(o.fraction, 0.5, 1e-12);
    EXPECT_NEAR(o.remaining_iterations, 2.0, 1e-12);
    // Exactly geometric: 4 more to 1e-6, where log(1e-4) / log(0.1) rounds to 4.000000000000001.
    EXPECT_EQ(convergence_outlook({1.0, 0.1, 0.01}, 1e-6).remaining_iterations, 4.0);
    // The rate is the geometric mean of the last three ratios (0.1, 0.5, 0.5 -> 0.292): 5 more
    // iterations to 1e-4 from 0.0225 (the last ratio alone would say 8, all four 6).
    o = outlook({1.0, 0.9, 0.09, 0.045, 0.0225});
    EXPECT_EQ(o.remaining_iterations, 5.0);
    EXPECT_NEAR(o.fraction, std::log(1.0 / 0.0225) / std::log(1e4), 1e-12);
    // Not falling: unknown; below the tolerance: done.
    EXPECT_TRUE(std::isnan(outlook({1.0, 0.5, 0.6, 0.7, 0.8}).remaining_iterations));
    EXPECT_NEAR(outlook({1.0, 0.5, 0.6, 0.7, 0.8}).fraction, std::log(1.0 / 0.8) / std::log(1e4), 1e-12);
    o = outlook({1.0, 1e-3, 5e-5});
    EXPECT_EQ(o.fraction, 1.0);
    EXPECT_EQ(o.remaining_iterations, 0.0);
    // A change above the first one: no way made.
    EXPECT_EQ(outlook({0.5, 2.0}).fraction, 0.0);

    // The run: 4 solves; the first took 10 s. The second has run 3 s for 3 iterations (1 s each)
    // with 2 left: 2 s, plus the last two solves at 10 s each.
    RunOutlook r = run_outlook({1.0, 0.1, 1e-2}, 1e-4, 3.0, 1.0, 1, 10.0, 4);
    EXPECT_NEAR(r.fraction, 1.5 / 4, 1e-12);
    EXPECT_NEAR(r.seconds_left, 2.0 + 2 * 10.0, 1e-12);
    // No solve complete yet: the later ones are taken to last as long as this one will (5 s).
    r = run_outlook({1.0, 0.1, 1e-2}, 1e-4, 3.0, 1.0, 0, 0.0, 2);
    EXPECT_NEAR(r.seconds_left, 2.0 + 5.0, 1e-12);
    // A first iteration that carried 4 s of set-up (ended at 5 s, then 1 s per iteration): the
    // 2 iterations left take 2 s, not 2 x 7/3 s, and the next solve 7 + 2 s.
    r = run_outlook({1.0, 0.1, 1e-2}, 1e-4, 7.0, 5.0, 0, 0.0, 2);
    EXPECT_NEAR(r.seconds_left, 2.0 + 9.0, 1e-12);
    // The current solve's rate is unknown: with no solve complete, so is the ETA; with two
    // complete in 16 s, this one (at 3 s) takes the mean 8 s, 5 s more, and the last one 8 s.
    EXPECT_TRUE(std::isnan(run_outlook({1.0}, 1e-4, 1.0, 1.0, 0, 0.0, 2).seconds_left));
    r = run_outlook({1.0}, 1e-4, 3.0, 3.0, 2, 16.0, 4);
    EXPECT_NEAR(r.seconds_left, 5.0 + 8.0, 1e-12);
    // ... and never less than nothing when it has already run longer than the mean.
    EXPECT_NEAR(run_outlook({1.0}, 1e-4, 10.0, 10.0, 2, 16.0, 3).seconds_left, 0.0, 1e-12);
}

}  // namespace
}  // namespace nimbus
