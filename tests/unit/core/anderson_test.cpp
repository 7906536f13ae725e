// Anderson acceleration (src/core/anderson.h) on fixed-point problems with known answers, the
// global vector split over the ranks.
#include <gtest/gtest.h>

#include <mpi.h>

#include <array>
#include <cmath>
#include <vector>

#include "src/core/anderson.h"
#include "src/core/decomposition.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr int kN = 40;  // global length

// This rank's part of [0, kN): the split of Decomposition's axes.
std::pair<int, int> my_range() {
    const int size = test::world_size(), rank = test::world_rank();
    return {Decomposition::split_lo(kN, size, rank), Decomposition::split_lo(kN, size, rank + 1)};
}

// G(x) = M x + c with M diagonal, eigenvalues from {0.95, -0.9, 0.5, 0.99} cycling over the
// entries: fixed point x* = c / (1 - M). Plain iteration converges as 0.99^k.
double eig(int i) { return std::array<double, 4>{0.95, -0.9, 0.5, 0.99}[static_cast<size_t>(i % 4)]; }
double rhs(int i) { return 1.0 + 0.1 * i; }

std::vector<double> apply_G(const std::vector<double>& x, int lo) {
    std::vector<double> g(x.size());
    for (size_t i = 0; i < x.size(); ++i) g[i] = eig(lo + static_cast<int>(i)) * x[i] + rhs(lo + static_cast<int>(i));
    return g;
}

double error_to_fixed_point(const std::vector<double>& x, int lo) {
    double e = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
        const int gi = lo + static_cast<int>(i);
        e = std::max(e, std::abs(x[i] - rhs(gi) / (1.0 - eig(gi))));
    }
    MPI_Allreduce(MPI_IN_PLACE, &e, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    return e;
}

TEST(Anderson, SolvesALinearFixedPointInAsManyStepsAsEigenvalues) {
    // On a linear map AA(m) is GMRES in disguise (Walker & Ni 2011, Theorem 2.2): with 4
    // distinct eigenvalues and depth 5 it is exact after 4 differences (step 6); plain
    // iteration would need ~2 700 steps (0.99^k < 1e-12).
    const auto [lo, hi] = my_range();
    std::vector<double> x(static_cast<size_t>(hi - lo), 0.0);
    AndersonMixer aa(MPI_COMM_WORLD, 5, 1.0);
    for (int k = 0; k < 6; ++k) x = aa.next(x, apply_G(x, lo));
    EXPECT_LT(error_to_fixed_point(x, lo), 1e-8);
    EXPECT_EQ(aa.restarts(), 0);
}

TEST(Anderson, RanksWithoutEntriesKeepInStep) {
    // The whole vector on rank 0, none on the others (a rank whose slab holds no cell of the
    // medium): every rank must make the same reduction, and the answer is rank 0's alone. The
    // history was kept only where the vector had entries, and 3 ranks of the flux limiter failed
    // with MPI_ERR_TRUNCATE.
    const int lo = 0, n = test::world_rank() == 0 ? kN : 0;
    std::vector<double> x(static_cast<size_t>(n), 0.0);
    AndersonMixer aa(MPI_COMM_WORLD, 5, 1.0);
    for (int k = 0; k < 6; ++k) x = aa.next(x, apply_G(x, lo));
    EXPECT_LT(error_to_fixed_point(x, lo), 1e-8);
}

TEST(Anderson, DepthZeroIsTheDampedIteration) {
    const auto [lo, hi] = my_range();
    std::vector<double> x(static_cast<size_t>(hi - lo), 0.0), y = x;
    AndersonMixer aa(MPI_COMM_WORLD, 0, 0.5);
    for (int k = 0; k < 5; ++k) {
        x = aa.next(x, apply_G(x, lo));
        const auto g = apply_G(y, lo);
        for (size_t i = 0; i < y.size(); ++i) y[i] = 0.5 * (y[i] + g[i]);
        for (size_t i = 0; i < y.size(); ++i) ASSERT_DOUBLE_EQ(x[i], y[i]) << k << " " << i;
        EXPECT_EQ(aa.columns_used(), 0);
    }
}

TEST(Anderson, MixingChangedMidwayIsUsedFromTheNextStep) {
    // Depth 0: x1 = x0 + 1.0 f0, then x2 = x1 + 0.25 f1.
    AndersonMixer aa(MPI_COMM_WORLD, 0, 1.0);
    std::vector<double> x = aa.next({0.0}, {4.0});
    EXPECT_DOUBLE_EQ(x[0], 4.0);
    aa.set_mixing(0.25);
    x = aa.next(x, {8.0});
    EXPECT_DOUBLE_EQ(x[0], 5.0);
}

TEST(Anderson, NonlinearContractionConvergesFasterThanPicard) {
    // x = cos(x) + 0.1 x^2 / (1 + x^2) per entry, coupled to its neighbour through a mean: a
    // smooth contraction. AA(5) reaches 1e-12 in fewer than a third of Picard's steps.
    const auto [lo, hi] = my_range();
    const size_t n = static_cast<size_t>(hi - lo);
    auto G = [&](const std::vector<double>& x) {
        double s = 0.0;
        for (double v : x) s += v;
        MPI_Allreduce(MPI_IN_PLACE, &s, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        std::vector<double> g(n);
        for (size_t i = 0; i < n; ++i)
            g[i] = std::cos(x[i]) + 0.1 * x[i] * x[i] / (1 + x[i] * x[i]) + 0.3 * s / kN + 0.01 * (lo + i);
        return g;
    };
    auto steps = [&](int depth) {
        AndersonMixer aa(MPI_COMM_WORLD, depth, 1.0);
        std::vector<double> x(n, 0.0);
        for (int k = 1; k <= 500; ++k) {
            const auto g = G(x);
            double r = 0.0;
            for (size_t i = 0; i < n; ++i) r = std::max(r, std::abs(g[i] - x[i]));
            MPI_Allreduce(MPI_IN_PLACE, &r, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
            if (r < 1e-12) return k;
            x = aa.next(x, g);
        }
        return 1000;
    };
    const int picard = steps(0), anderson = steps(5);
    if (test::world_rank() == 0) std::printf("steps to 1e-12: Picard %d, Anderson(5) %d\n", picard, anderson);
    EXPECT_LT(picard, 500);
    EXPECT_LT(3 * anderson, picard);
}

TEST(Anderson, RefusesBadSettingsAndChangingLengths) {
    EXPECT_THROW(AndersonMixer(MPI_COMM_WORLD, 9, 1.0), Error);
    EXPECT_THROW(AndersonMixer(MPI_COMM_WORLD, 2, 0.0), Error);
    AndersonMixer aa(MPI_COMM_WORLD, 2, 1.0);
    EXPECT_THROW(aa.set_mixing(1.5), Error);
    EXPECT_THROW(aa.next({1.0, 2.0}, {1.0}), Error);
    aa.next({1.0, 2.0}, {0.5, 0.5});
    EXPECT_THROW(aa.next({1.0}, {1.0}), Error);
}

}  // namespace
}  // namespace nimbus
