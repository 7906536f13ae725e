// The ETA of a phase of equal units (LPM's map sweeps, the light pass's terms): the rate since
// the first report, so that a first unit carrying the phase's set-up does not inflate it.
#include <gtest/gtest.h>

#include "src/core/progress.h"

namespace nimbus {
namespace {

// 36 units, the first done at 10 s (set-up included), then one a second: at 14 s with 5 done,
// 31 are left at 1 s each; the mean rate since the start would say 14 × 31 / 5 = 86.8 s.
TEST(Progress, EtaIsTheRateSinceTheFirstReport) {
    EXPECT_DOUBLE_EQ(progress_eta(5, 36, 1, 10.0, 0.0, 14.0), 31.0);
    // Offsets (a later solve's first unit, a start time that is not 0) change nothing.
    EXPECT_DOUBLE_EQ(progress_eta(17, 48, 13, 110.0, 100.0, 114.0), 31.0);
}

TEST(Progress, EtaBeforeASecondUnitIsTheMeanRateSinceTheStart) {
    EXPECT_DOUBLE_EQ(progress_eta(1, 36, 1, 10.0, 0.0, 10.0), 350.0);  // only the first unit
    EXPECT_DOUBLE_EQ(progress_eta(4, 8, -1, 0.0, 0.0, 2.0), 2.0);      // no first report recorded
    EXPECT_DOUBLE_EQ(progress_eta(0, 8, -1, 0.0, 0.0, 2.0), 0.0);      // nothing done: no rate
    EXPECT_DOUBLE_EQ(progress_eta(8, 8, 1, 1.0, 0.0, 9.0), 0.0);       // done
}

}  // namespace
}  // namespace nimbus
