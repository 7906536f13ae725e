// `nimbus compare` warns when A and B are runs of different media: max_rel_difference of the
// two density fields against kSameMediumTolerance. Equal media (to the float32 round-off of the
// output) pass; a changed density scale or a moved cloud does not.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "src/analysis/compare.h"
#include "src/core/error.h"

namespace nimbus {
namespace {

std::vector<double> cloud(double scale, int shift) {
    std::vector<double> rho(64, 0.0);
    for (int c = 10; c < 30; ++c) rho[static_cast<size_t>(c + shift)] = scale * (1.0 + 0.1 * c);
    return rho;
}

TEST(SameMedium, EqualDensitiesAndRoundOffPass) {
    const std::vector<double> b = cloud(1.0, 0);
    EXPECT_EQ(max_rel_difference(b, b), 0.0);
    std::vector<double> a = b;
    for (double& v : a) v = static_cast<double>(static_cast<float>(v));  // what the HDF5 output keeps
    EXPECT_LE(max_rel_difference(a, b), kSameMediumTolerance);
    const std::vector<double> empty(64, 0.0);
    EXPECT_EQ(max_rel_difference(empty, empty), 0.0);
}

TEST(SameMedium, DifferentMediaAreFlagged) {
    const std::vector<double> b = cloud(1.0, 0);
    EXPECT_NEAR(max_rel_difference(cloud(1.5, 0), b), 0.5, 1e-12);  // density scale 1.5
    EXPECT_GT(max_rel_difference(cloud(1.0, 3), b), kSameMediumTolerance);  // the cloud moved
    EXPECT_EQ(max_rel_difference(b, std::vector<double>(64, 0.0)), std::numeric_limits<double>::infinity());
    EXPECT_THROW(max_rel_difference(b, std::vector<double>(63, 0.0)), Error);
}

}  // namespace
}  // namespace nimbus
