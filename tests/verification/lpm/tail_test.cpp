// The tails of solvers/lpm/tail.h: after a few iterations on a thick, bright cube (tau 16
// across, albedo 0.99, g 0.6; the iteration converges at ~0.9 per round), the fluence with each
// tail (and DSA, tail "dsa") against the same LPM iterated to convergence (max U < 1e-6 of the
// first-scatter max).
// The converged LPM is the tails' target (same angular discretization), so this isolates what
// the tail adds. Checked: relative L2 of the fluence; the geometric tail must cut the bare
// iteration's error to < 60%, the diffusion tail to < 25% and below 15% absolute (bounds set
// from the measured values printed by the test, with margin); the geometric factor is
// rho/(1-rho) of the measured decay ratio.
#include <gtest/gtest.h>

#include <cmath>

#include "solvers/lpm/tail.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/lpm/lpm_world.h"

namespace nimbus {
namespace {

using test::LpmWorld;
using test::lpm_options;

double rel_l2(const LpmWorld& w, const Field<double>& a, const Field<double>& ref) {
    const double e = w.sum([&](int i, int j, int k) { return std::pow(a(i, j, k) - ref(i, j, k), 2); });
    const double n = w.sum([&](int i, int j, int k) { return std::pow(ref(i, j, k), 2); });
    return std::sqrt(e / n);
}

TEST(LpmTail, GeometricFactorIsRhoOverOneMinusRho) {
    EXPECT_DOUBLE_EQ(lpm::geometric_tail_factor(0.9, 1.0), 9.0);
    EXPECT_DOUBLE_EQ(lpm::geometric_tail_factor(0.0, 1.0), 0.0);
    EXPECT_DOUBLE_EQ(lpm::geometric_tail_factor(2.0, 1.0), lpm::kRhoMax / (1.0 - lpm::kRhoMax));
}

TEST(LpmTail, TailsRecoverTheConvergedFluenceOfAThickBrightCube) {
    // MPI_COMM_SELF: ~150 iterations of per-step messages would dominate at 2 ranks.
    LpmWorld w(MPI_COMM_SELF, {16, 16, 16}, {false, false, false}, [](int, int, int) { return 1.0; },
               BandOptics{"gray", 1.0, 0.99, 0.6}, {{"sun", normalized(Vec3{0.3, 0.2, -1.0}), {1.0}}});
    const lpm::BandResult ref = w.solve(lpm_options(3, 1, 400, 1e-6));
    ASSERT_LT(ref.max_U.back(), 1e-6);
    for (int it : {3, 5}) {
        double err[4];
        const char* names[4] = {"none", "geometric", "diffusion", "dsa"};
        for (int t = 0; t < 4; ++t) {
            LpmOptions o = lpm_options(3, 1, it);
            o.tail = names[t];
            const lpm::BandResult r = w.solve(o);
            err[t] = rel_l2(w, r.fluence, ref.fluence);
            if (t == 1) {
                const double rho = r.remaining_history[static_cast<size_t>(it - 1)] /
                                   r.remaining_history[static_cast<size_t>(it - 2)];
                EXPECT_NEAR(r.tail_factor, rho / (1.0 - rho), 1e-12 * r.tail_factor);
            }
        }
        if (test::world_rank() == 0)
            std::printf("    tau-16 cube, a 0.99, g 0.6, %d iterations (converged: %d): fluence rel L2 "
                        "none %.3f, geometric %.3f, diffusion %.3f, dsa %.4f\n",
                        it, ref.iterations, err[0], err[1], err[2], err[3]);
        // Measured (3 / 5 iterations): none 0.668 / 0.535, geometric 0.341 / 0.233,
        // diffusion 0.121 / 0.100 (the P1 tail's own error: g 0.6 is not isotropic).
        EXPECT_LT(err[1], 0.6 * err[0]);
        EXPECT_LT(err[2], 0.25 * err[0]);
        EXPECT_LT(err[2], err[1]);
        EXPECT_LT(err[2], 0.15);
        // DSA: transport corrects the P1 corrections round by round (measured: 0.0155 / 0.0020).
        EXPECT_LT(err[3], 0.2 * err[2]);
    }
}

// DSA leaves LPM's fixed point where it was: iterated to convergence with the corrections fed
// back, the fluence equals the plain iteration's converged fluence (the corrections vanish as the
// iterate's changes do), in far fewer rounds; and the energy bookkeeping closes after any count
// (every S(f) put into U is taken out once).
TEST(LpmTail, DsaConvergesToTheSameFixedPointInFewerRounds) {
    LpmWorld w(MPI_COMM_SELF, {16, 16, 16}, {false, false, false}, [](int, int, int) { return 1.0; },
               BandOptics{"gray", 1.0, 0.99, 0.6}, {{"sun", normalized(Vec3{0.3, 0.2, -1.0}), {1.0}}});
    const lpm::BandResult ref = w.solve(lpm_options(3, 1, 400, 1e-7));
    ASSERT_LT(ref.max_U.back(), 1e-7);
    LpmOptions o = lpm_options(3, 1, 400, 1e-7);
    o.tail = "dsa";
    const lpm::BandResult r = w.solve(o);
    ASSERT_LT(r.max_U.back(), 1e-7);
    const double err = rel_l2(w, r.fluence, ref.fluence);
    if (test::world_rank() == 0)
        std::printf("    converged: plain %d rounds, dsa %d rounds (%d corrections); fluence rel L2 %.2e\n",
                    ref.iterations, r.iterations, r.dsa_corrections, err);
    EXPECT_LT(err, 1e-5);
    EXPECT_LT(r.iterations, ref.iterations / 3);
    EXPECT_EQ(r.dsa_corrections, r.iterations);  // stopped by epsilon: every round corrected (measured: 25 of 160)
    EXPECT_TRUE(r.dsa_diverged_max_U.empty());
    for (int it : {1, 2, 4}) {
        LpmOptions oi = lpm_options(3, 1, it);
        oi.tail = "dsa";
        const lpm::BandResult ri = w.solve(oi);
        EXPECT_NEAR(ri.escaped + ri.absorbed + ri.remaining + ri.truncated, ri.source, 1e-11 * ri.source) << it;
    }
}

// The same on a domain periodic in x and y, where the ±X/±Y maps are swept cyclically: a slab
// (scenes/slab.toml at half its height, 12 x 12 x 32: tau 2 over cells [8, 24), albedo 0.9,
// g 0.5, sun overhead, p 6). DSA's corrections leave U negative, and the cyclic sweeps' filling
// test on the map's signed power held at once for such light, so the vacuum layers above and
// below kept part of their dark start and the light missing was booked as `truncated` (before
// the fix: -4.7 W of 112 after 3 rounds, -5.1 W after 6, vacuum layer means not constant, and
// DSA iterated to 1e-7 converged 0.037 (rel L2) away from the plain iteration; on the full
// scene, 64 layers: -11.1 W, fluence 1.07x). Now: nothing truncated after any count, constant
// vacuum layers, and the plain iteration's fixed point (measured 2.5e-7, 12 rounds against 30).
TEST(LpmTail, DsaOnAPeriodicSlabKeepsTheEnergyAndTheFixedPoint) {
    constexpr int kN = 12, kZ = 32, kLo = 8, kHi = 24;
    LpmWorld w(MPI_COMM_WORLD, {kN, kN, kZ}, {true, true, false},
               [](int, int, int k) { return k >= kLo && k < kHi ? 1.0 : 0.0; },
               BandOptics{"gray", 0.125, 0.9, 0.5}, {{"sun", Vec3{0.0, 0.0, -1.0}, {1.0}}});
    // Layer means of the fluence over x and y, all ranks.
    auto layer_means = [&](const Field<double>& f) {
        std::vector<double> mean(kZ, 0.0);
        for_each_cell(w.d.local(), [&](int i, int j, int k) { mean[static_cast<size_t>(k)] += f(i, j, k) / (kN * kN); });
        MPI_Allreduce(MPI_IN_PLACE, mean.data(), kZ, MPI_DOUBLE, MPI_SUM, w.d.comm());
        return mean;
    };
    for (int it : {3, 6}) {
        LpmOptions o = lpm_options(6, 1, it);
        o.tail = "dsa";
        const lpm::BandResult r = w.solve(o);
        EXPECT_NEAR(r.escaped + r.absorbed + r.remaining + r.truncated, r.source, 1e-11 * r.source) << it;
        EXPECT_LT(std::abs(r.truncated), 1e-8 * r.source) << it;  // before the fix: 4.2%, 4.5%
        const std::vector<double> mean = layer_means(r.fluence);
        for (int k = kHi + 1; k < kZ; ++k) EXPECT_NEAR(mean[k], mean[kHi], 1e-7 * mean[kHi]) << it << " " << k;
        for (int k = 1; k < kLo; ++k) EXPECT_NEAR(mean[k], mean[0], 1e-7 * mean[0]) << it << " " << k;
    }
    const lpm::BandResult ref = w.solve(lpm_options(6, 1, 400, 1e-7));
    LpmOptions o = lpm_options(6, 1, 400, 1e-7);
    o.tail = "dsa";
    const lpm::BandResult r = w.solve(o);
    ASSERT_LT(r.max_U.back(), 1e-7);
    const double err = rel_l2(w, r.fluence, ref.fluence);
    if (test::world_rank() == 0)
        std::printf("    periodic slab, converged: plain %d rounds, dsa %d; fluence rel L2 %.2e, truncated %.2e W of %.1f\n",
                    ref.iterations, r.iterations, err, r.truncated, r.source);
    EXPECT_LT(err, 1e-5);  // before the fix: 0.037
}

// On cells of 20 optical depths at albedo 0.999 (a box of 4³ such cells) DSA's P1 corrections
// over-correct: max |U| grew 270, 2887, 3923 times the first-scatter maximum over 3 rounds, the
// fluence reached 1145 (Monte Carlo: 2.7) with negative energies. The growth from the first
// round to the second is caught and the band is solved again with the plain P1 tail: the result
// is that solve's, bit for bit, and says what happened.
TEST(LpmTail, DivergingDsaFallsBackToThePlainTail) {
    LpmWorld w(MPI_COMM_WORLD, {8, 8, 8}, {false, false, false},
               [](int i, int j, int k) { return i >= 2 && i < 6 && j >= 2 && j < 6 && k >= 2 && k < 6 ? 1.0 : 0.0; },
               BandOptics{"gray", 20.0, 0.999, 0.0}, {{"sun", Vec3{0.0, 0.0, -1.0}, {1.0}}});
    LpmOptions o = lpm_options(6, 1, 3);
    o.tail = "dsa";
    const lpm::BandResult r = w.solve(o);
    ASSERT_EQ(r.dsa_diverged_max_U.size(), 2u);
    EXPECT_GT(r.dsa_diverged_max_U[1], r.dsa_diverged_max_U[0]);
    EXPECT_GT(r.dsa_diverged_max_U[0], 10.0);  // measured 270
    o.tail = "diffusion";
    const lpm::BandResult plain = w.solve(o);
    EXPECT_EQ(r.dsa_corrections, 0);
    EXPECT_EQ(r.iterations, plain.iterations);
    double diff = 0.0, lo = 0.0;
    w.sum([&](int i, int j, int k) {
        diff = std::max(diff, std::abs(r.fluence(i, j, k) - plain.fluence(i, j, k)));
        lo = std::min(lo, r.fluence(i, j, k));
        return 0.0;
    });
    EXPECT_EQ(diff, 0.0);
    EXPECT_GE(lo, 0.0);
    EXPECT_NEAR(r.escaped + r.absorbed + r.remaining + r.truncated, r.source, 1e-11 * r.source);
    EXPECT_GT(r.absorbed, 0.0);
    EXPECT_GT(r.escaped, 0.0);
}

}  // namespace
}  // namespace nimbus
