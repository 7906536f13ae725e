// Verification of the forward Monte Carlo (solvers/montecarlo): Philox known answers; slab
// reflectance/transmittance and interior fluence against the independent slab reference on
// the issue's whole grid of 24 cases (z-tests with fixed seeds); energy balance; pure absorber
// and Beer-Lambert; same seed same result; 1 rank (MPI_COMM_SELF) against all ranks; the
// replicated-memory limit; the same checks with the forced first collision
// (ForwardSettings::forced_first_collision); the stops at a target error and at a time budget,
// and the progress ETA.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <vector>

#include "solvers/montecarlo/forward.h"
#include "solvers/montecarlo/montecarlo.h"
#include "solvers/montecarlo/philox.h"
#include "solvers/montecarlo/trace_lanes.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"
#include "tests/support/slab_reference.h"

namespace nimbus::mc {
namespace {

TEST(Philox, MatchesRandom123KnownAnswers) {
    EXPECT_EQ(philox4x32_10({0, 0, 0, 0}, {0, 0}),
              (Philox4x32{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u}));
    EXPECT_EQ(philox4x32_10({0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu}, {0xffffffffu, 0xffffffffu}),
              (Philox4x32{0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu}));
    EXPECT_EQ(philox4x32_10({0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u}, {0xa4093822u, 0x299f31d0u}),
              (Philox4x32{0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u}));
}

// A homogeneous slab of nx x ny x nz unit cells, periodic in x and y, density 1.
struct Slab {
    Decomposition d;
    Medium m;
    Slab(MPI_Comm comm, double tau0, double albedo, double g, Int3 n = {8, 8, 32}, double rho = 1.0)
        : d(comm, n, {0, 0, 0}, {true, true, false}) {
        m.grid.n = n;
        m.grid.h = 1.0;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = rho; });
        m.bands = {BandOptics{"gray", tau0 / n[2], albedo, g}};
    }
};

DirectionalLight beam(double mu0) {
    return {"sun", {std::sqrt(1.0 - mu0 * mu0), 0.0, -mu0}, {1.0}};
}

MonteCarloOptions options(std::int64_t photons, std::uint64_t seed = 7) {
    MonteCarloOptions o;
    o.photons = photons;
    o.seed = seed;
    o.batches = 32;
    return o;
}

struct SlabCase {
    double tau0, albedo, g, mu0;
    std::int64_t photons;
};

// One case of the slab grid below, 1.5 x 10^5 photons in 128 batches: R and T (diffuse only)
// and the direct beam within 3.5 standard errors of the slab reference; the per-cell interior
// fluence z = (MC - reference cell average) / stderr has RMS in [0.85, 1.25] over the 2048 cells
// and no |z| > 5.5. Returns the z-values of R and T.
std::array<double, 2> check_slab_case(double tau0, double albedo, double g, double mu0, std::uint64_t seed) {
    constexpr std::int64_t kPhotons = 150000;
    Slab slab(MPI_COMM_WORLD, tau0, albedo, g);
    MonteCarloOptions o = options(kPhotons, seed);
    o.batches = 128;
    const ForwardResult r = trace_forward(slab.d, slab.m, {beam(mu0)}, o);
    const Counters& m = r.counters[0];
    const Counters& se = r.counters_stderr[0];
    const double P_in = m[incident];
    EXPECT_NEAR(P_in, mu0 * 64.0, 1e-9);
    const double R = m[escaped_zhi] / P_in, sR = se[escaped_zhi] / P_in;
    const double T = m[escaped_zlo] / P_in, sT = se[escaped_zlo] / P_in;

    test::SlabProblem p{tau0, albedo, g, mu0};
    p.profile_levels = 64;
    const test::SlabSolution ref = test::solve_slab(p);
    const double zR = (R - ref.reflected) / sR, zT = (T - ref.transmitted_diffuse) / sT;
    EXPECT_LT(std::abs(zR), 3.5) << "R: MC " << R << " ± " << sR << ", reference " << ref.reflected;
    EXPECT_LT(std::abs(zT), 3.5) << "T: MC " << T << " ± " << sT << ", reference " << ref.transmitted_diffuse;
    EXPECT_LT(sR, 0.01 * ref.reflected + 1e-3);  // the estimate is actually informative
    // direct beam: binomial; its batch stderr is 0 when no photon gets through (tau0/mu0 = 20)
    const double t_dir = std::exp(-tau0 / mu0);
    const double s_dir = std::max(se[escaped_direct] / P_in, std::sqrt(t_dir * (1 - t_dir) / kPhotons));
    EXPECT_NEAR(m[escaped_direct] / P_in, t_dir, 3.5 * s_dir);

    // Cell k spans depths tau0 (31 - k, 32 - k) / 32: Simpson over reference levels.
    double z2 = 0.0, zmax = 0.0, count = 0.0;
    for_each_cell(slab.d.local(), [&](int i, int j, int k) {
        const size_t l = static_cast<size_t>(2 * (31 - k));
        const double expect = (ref.fluence[l] + 4.0 * ref.fluence[l + 1] + ref.fluence[l + 2]) / 6.0;
        const double z = (r.fluence[0](i, j, k) - expect) / r.fluence_stderr[0](i, j, k);
        z2 += z * z;
        zmax = std::max(zmax, std::abs(z));
        count += 1.0;
    });
    double sums[2] = {z2, count}, tot[2];
    MPI_Allreduce(sums, tot, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    double zmax_all = 0.0;
    MPI_Allreduce(&zmax, &zmax_all, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    const double rms = std::sqrt(tot[0] / tot[1]);
    EXPECT_GT(rms, 0.85);
    EXPECT_LT(rms, 1.25);
    EXPECT_LT(zmax_all, 5.5);
    if (test::world_rank() == 0)
        std::printf("    tau0 %4g a %4g g %4g mu0 %g: R %.5f ± %.5f (ref %.5f, z %+.2f), T %.5f ± %.5f "
                    "(ref %.5f, z %+.2f), fluence z rms %.3f max %.2f\n",
                    tau0, albedo, g, mu0, R, sR, ref.reflected, zR, T, sT, ref.transmitted_diffuse, zT, rms,
                    zmax_all);
    return {zR, zT};
}

// The issue's slab grid, every combination: g {0, 0.85} x albedo {0.9, 0.99, 1} x tau0 {1, 10}
// x incidence {0°, 60°}, 24 cases (check_slab_case), case i with seed 7 + i; jointly, the RMS
// of the 48 R and T z-values lies in [0.6, 1.4].
//
// Why this criterion rather than the issue's literal one (3 standard errors per value at 10^5
// photons; the rates are for independent t-distributed z-values): that one fails by chance in
// 15% (127 degrees of freedom) to 22% (31) of runs over 48 values, and its per-cell |z| < 5
// over 24 x 2048 cells in 9% (127) to 65% (31): about 28% of runs in all with 128 batches,
// 76% with 32, so a correct change elsewhere would often trip it. Measured at 10^5 photons:
// seed 9 (g 0, a 0.9, tau0 10, normal) gave T z = -4.05, while 179 other seeds of that case
// gave |z| < 2.8 with mean -0.05 (no bias), and 600 seeds of another case (albedo 1, tau0 10,
// 60°) showed no heavy tail: noise.
// - The same tolerance on the estimate, a less noisy estimate: 3.5 standard errors at 1.5x the
//   photons is 3.5 / sqrt(1.5) = 2.86 of the old ones (per cell 5.5 -> 4.49), narrower than
//   before, so the test is at least as powerful against any bias the old one was meant to
//   catch (R and T of one case +3 old standard errors: caught 82% against 79%), and chance
//   failures drop to about 5% of runs.
// - The joint RMS bound detects what no per-value bound can: overestimated standard errors
//   (every |z| small; z scaled by 0.5: 97% against 0%), and it catches a bias shared by many
//   cases (+1 old standard error in all 48: 93% against 69%).
// - 128 batches rather than 32: the same photons (so the same estimates), but standard errors
//   with 127 degrees of freedom instead of 31, whose tails made most chance failures of the
//   per-cell bound (|t_31| > 5 is 12x as likely as |t_127| > 5). With 32 batches and seed 7, one
//   cell (g 0, a 1, tau0 10, 60°) had z = -6.30; with 128 batches, the same photons, 4.28.
// - Case i draws with seed 7 + i: cases that share a seed share their photons' first
//   collisions, so their z-values move together (seen: zR 1.31, 1.20, 1.17 for albedo 0.9,
//   0.99, 1 with one seed), and the RMS bound needs independent values.
TEST(SlabAgainstReference, EveryCaseOfTheIssuesGrid) {
    std::vector<double> z_rt;
    std::uint64_t seed = 7;
    for (const double g : {0.0, 0.85})
        for (const double albedo : {0.9, 0.99, 1.0})
            for (const double tau0 : {1.0, 10.0})
                for (const double mu0 : {1.0, 0.5}) {
                    SCOPED_TRACE(::testing::Message() << "tau0 " << tau0 << " albedo " << albedo << " g " << g
                                                      << " mu0 " << mu0 << " seed " << seed);
                    const std::array<double, 2> z = check_slab_case(tau0, albedo, g, mu0, seed++);
                    z_rt.insert(z_rt.end(), z.begin(), z.end());
                }
    ASSERT_EQ(z_rt.size(), 48u);
    double z2 = 0.0;
    for (const double z : z_rt) z2 += z * z;
    const double rms = std::sqrt(z2 / static_cast<double>(z_rt.size()));
    EXPECT_GT(rms, 0.6);
    EXPECT_LT(rms, 1.4);
    if (test::world_rank() == 0) std::printf("    R and T over the 24 cases: z rms %.3f\n", rms);
}

// A cloud-like blob, no periodic axes, sun and sky: every watt that enters is absorbed or
// escapes. Exactly (round-off) when roulette's zero-mean weight change is counted, and to
// 1e-3 without it.
// The photon budget split over light terms: proportional to power by largest remainder, at
// least one photon per batch for a lit term, counts summing to the budget; powers whose sum
// overflows a double still split; a non-finite power is an error (it used to loop forever on
// NaN shares).
TEST(Forward, PhotonsPerLight) {
    EXPECT_EQ(mc::photons_per_light({3.0, 1.0, 0.0}, 400, 4), (std::vector<std::int64_t>{300, 100, 0}));
    EXPECT_EQ(mc::photons_per_light({1000.0, 1e-6}, 100, 4), (std::vector<std::int64_t>{96, 4}));
    EXPECT_EQ(mc::photons_per_light({1.0, 1.0, 1.0}, 100, 1), (std::vector<std::int64_t>{34, 33, 33}));
    EXPECT_EQ(mc::photons_per_light({1e308, 1e308}, 100, 4), (std::vector<std::int64_t>{50, 50}));
    EXPECT_THROW(mc::photons_per_light({1.0, std::numeric_limits<double>::infinity()}, 100, 4), Error);
}

TEST(Forward, EnergyBalance) {
    const Int3 n{12, 10, 8};
    Decomposition d(MPI_COMM_WORLD, n);
    Medium m;
    m.grid.n = n;
    m.grid.h = 2.0;
    m.rho = Field<double>(d.local(), 1, 1, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double x = (i + 0.5) / n[0] - 0.5, y = (j + 0.5) / n[1] - 0.5, z = (k + 0.5) / n[2] - 0.5;
        m.rho(i, j, k) = std::max(0.0, 1.0 - 4.0 * (x * x + y * y + z * z));
    });
    m.bands = {BandOptics{"r", 0.8, 0.9, 0.85}, BandOptics{"g", 0.8, 0.9, 0.85}, BandOptics{"b", 1.5, 0.99, 0.5}};
    const std::vector<DirectionalLight> lights{
        {"sun", normalized(Vec3{0.5, 0.3, -0.8}), {1.0, 0.9, 0.8}},
        {"sky[0]", normalized(Vec3{-0.2, 0.7, -0.4}), {0.1, 0.2, 0.3}}};
    const ForwardResult r = trace_forward(d, m, lights, options(60000));
    for (int b = 0; b < 3; ++b) {
        const Counters& c = r.counters[static_cast<size_t>(b)];
        double escaped = c[escaped_direct];
        for (int f = 0; f < 6; ++f) escaped += c[escaped_xlo + f];
        EXPECT_NEAR(c[absorbed] + escaped - c[roulette_net], c[incident], 1e-12 * c[incident]);
        EXPECT_NEAR(c[absorbed] + escaped, c[incident], 1e-3 * c[incident]);
        EXPECT_GT(c[absorbed], 0.0);
        // incident = Σ E0 A_projected, A_projected over the three entry faces (h = 2 m)
        const double area_sun = (0.5 * 10 * 8 + 0.3 * 12 * 8 + 0.8 * 12 * 10) / norm(Vec3{0.5, 0.3, -0.8}) * 4.0;
        const double area_sky = (0.2 * 10 * 8 + 0.7 * 12 * 8 + 0.4 * 12 * 10) / norm(Vec3{-0.2, 0.7, -0.4}) * 4.0;
        EXPECT_NEAR(c[incident], lights[0].E0[static_cast<size_t>(b)] * area_sun + lights[1].E0[static_cast<size_t>(b)] * area_sky, 1e-9);
    }
    // bands r and g share optics and are traced once: under one light their tallies are
    // exactly proportional to E0
    const ForwardResult sun = trace_forward(d, m, {lights[0]}, options(3000));
    EXPECT_NEAR(sun.counters[1][absorbed] / sun.counters[0][absorbed], 0.9, 1e-14);
    EXPECT_NEAR(sun.counters[1][diffuse_volume] / sun.counters[0][diffuse_volume], 0.9, 1e-14);
}

// A pure absorber's tallies (albedo 0, 16 cells deep, optical depth tau0, beam at mu0): the
// diffuse fluence is exactly zero and the unscattered tally is the cell average of
// E0 exp(-kappa s / mu0) over depth, checked as z = (tally - exact) / stderr over all cells.
void expect_beer_lambert(const ForwardResult& r, const Slab& slab, double tau0, double mu0) {
    const double kappa = tau0 / 16;
    double z2 = 0.0, count = 0.0, zmax = 0.0;
    for_each_cell(slab.d.local(), [&](int i, int j, int k) {
        EXPECT_EQ(r.fluence[0](i, j, k), 0.0);
        const double depth = 16 - (k + 1);
        const double expect = mu0 / kappa * (std::exp(-kappa * depth / mu0) - std::exp(-kappa * (depth + 1) / mu0));
        const double z = (r.reduced[0](i, j, k) - expect) / r.reduced_stderr[0](i, j, k);
        z2 += z * z;
        count += 1.0;
        zmax = std::max(zmax, std::abs(z));
    });
    double sums[2] = {z2, count}, tot[2];
    MPI_Allreduce(sums, tot, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    const double rms = std::sqrt(tot[0] / tot[1]);
    EXPECT_GT(rms, 0.8);
    EXPECT_LT(rms, 1.3);
    EXPECT_LT(zmax, 5.0);
}

// Albedo 0: nothing scatters, so the diffuse fluence is exactly zero; the unscattered tally
// follows Beer-Lambert: the cell average of E0 exp(-kappa s / mu0) over depth.
TEST(Forward, PureAbsorberFollowsBeerLambert) {
    const double tau0 = 3.0, mu0 = 0.6;
    Slab slab(MPI_COMM_WORLD, tau0, 0.0, 0.85, {4, 4, 16});
    ForwardSettings s;
    s.tally_reduced = true;
    const ForwardResult r = trace_forward(slab.d, slab.m, {beam(mu0)}, options(40000), s);
    expect_beer_lambert(r, slab, tau0, mu0);
    const Counters& c = r.counters[0];
    EXPECT_EQ(c[escaped_zhi], 0.0);
    EXPECT_NEAR(c[escaped_direct] / c[incident], std::exp(-tau0 / mu0), 3.0 * r.counters_stderr[0][escaped_direct] / c[incident]);
    EXPECT_NEAR(c[absorbed] + c[escaped_direct], c[incident], 1e-12 * c[incident]);
}

// The forced first collision (photon.h): slab R and T within 3 standard errors of the slab
// reference and the interior fluence z-test as above; the direct beam is booked analytically,
// exp(-tau0 / mu0) for every ray of the slab.
TEST(Forward, ForcedFirstCollisionAgreesWithTheSlabReference) {
    ForwardSettings forced;
    forced.forced_first_collision = true;
    for (const SlabCase c : {SlabCase{1.0, 0.9, 0.0, 1.0, 200000}, SlabCase{10.0, 0.99, 0.85, 0.5, 100000}}) {
        Slab slab(MPI_COMM_WORLD, c.tau0, c.albedo, c.g);
        const ForwardResult r = trace_forward(slab.d, slab.m, {beam(c.mu0)}, options(c.photons), forced);
        const Counters& m = r.counters[0];
        const Counters& se = r.counters_stderr[0];
        const double P_in = m[incident];
        const double R = m[escaped_zhi] / P_in, sR = se[escaped_zhi] / P_in;
        const double T = m[escaped_zlo] / P_in, sT = se[escaped_zlo] / P_in;
        test::SlabProblem p{c.tau0, c.albedo, c.g, c.mu0};
        p.profile_levels = 64;
        const test::SlabSolution ref = test::solve_slab(p);
        EXPECT_NEAR(R, ref.reflected, 3.0 * sR) << "R: MC " << R << " ± " << sR << ", reference " << ref.reflected;
        EXPECT_NEAR(T, ref.transmitted_diffuse, 3.0 * sT) << "T: MC " << T << " ± " << sT << ", reference " << ref.transmitted_diffuse;
        EXPECT_LT(sR, 0.01 * ref.reflected + 1e-3);
        EXPECT_NEAR(m[escaped_direct] / P_in, std::exp(-c.tau0 / c.mu0), 1e-12);
        double z2 = 0.0, zmax = 0.0, count = 0.0;
        for_each_cell(slab.d.local(), [&](int i, int j, int k) {
            const size_t l = static_cast<size_t>(2 * (31 - k));
            const double expect = (ref.fluence[l] + 4.0 * ref.fluence[l + 1] + ref.fluence[l + 2]) / 6.0;
            const double z = (r.fluence[0](i, j, k) - expect) / r.fluence_stderr[0](i, j, k);
            z2 += z * z;
            zmax = std::max(zmax, std::abs(z));
            count += 1.0;
        });
        double sums[2] = {z2, count}, tot[2];
        MPI_Allreduce(sums, tot, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        double zmax_all = 0.0;
        MPI_Allreduce(&zmax, &zmax_all, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        const double rms = std::sqrt(tot[0] / tot[1]);
        EXPECT_GT(rms, 0.85);
        EXPECT_LT(rms, 1.25);
        EXPECT_LT(zmax_all, 5.0);
        if (test::world_rank() == 0)
            std::printf("    forced: tau0 %g a %g g %g mu0 %g: R %.5f ± %.5f (ref %.5f), T %.5f ± %.5f (ref %.5f), "
                        "fluence z rms %.3f max %.2f\n",
                        c.tau0, c.albedo, c.g, c.mu0, R, sR, ref.reflected, T, sT, ref.transmitted_diffuse, rms, zmax_all);
    }
}

// Forced first collision: the energy balance of the blob closes exactly with roulette's
// zero-mean change and to 1e-3 without it; a pure absorber's reduced tally (now the expected
// uncollided track along each entry ray) follows Beer-Lambert and absorbed + direct = incident.
TEST(Forward, ForcedFirstCollisionEnergyBalanceAndBeerLambert) {
    ForwardSettings forced;
    forced.forced_first_collision = true;
    const Int3 n{12, 10, 8};
    Decomposition d(MPI_COMM_WORLD, n);
    Medium m;
    m.grid.n = n;
    m.grid.h = 2.0;
    m.rho = Field<double>(d.local(), 1, 1, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double x = (i + 0.5) / n[0] - 0.5, y = (j + 0.5) / n[1] - 0.5, z = (k + 0.5) / n[2] - 0.5;
        m.rho(i, j, k) = std::max(0.0, 1.0 - 4.0 * (x * x + y * y + z * z));
    });
    m.bands = {BandOptics{"r", 0.8, 0.9, 0.85}, BandOptics{"b", 1.5, 0.99, 0.5}};
    const std::vector<DirectionalLight> lights{{"sun", normalized(Vec3{0.5, 0.3, -0.8}), {1.0, 0.8}},
                                               {"sky[0]", normalized(Vec3{-0.2, 0.7, -0.4}), {0.1, 0.3}}};
    const ForwardResult r = trace_forward(d, m, lights, options(60000), forced);
    for (int b = 0; b < 2; ++b) {
        const Counters& c = r.counters[static_cast<size_t>(b)];
        double escaped = c[escaped_direct];
        for (int f = 0; f < 6; ++f) escaped += c[escaped_xlo + f];
        EXPECT_NEAR(c[absorbed] + escaped - c[roulette_net], c[incident], 1e-12 * c[incident]);
        EXPECT_NEAR(c[absorbed] + escaped, c[incident], 1e-3 * c[incident]);
        EXPECT_GT(c[absorbed], 0.0);
    }

    const double tau0 = 3.0, mu0 = 0.6;
    Slab slab(MPI_COMM_WORLD, tau0, 0.0, 0.85, {4, 4, 16});
    forced.tally_reduced = true;
    const ForwardResult a = trace_forward(slab.d, slab.m, {beam(mu0)}, options(40000), forced);
    expect_beer_lambert(a, slab, tau0, mu0);
    const Counters& c = a.counters[0];
    EXPECT_EQ(c[escaped_zhi], 0.0);
    EXPECT_NEAR(c[escaped_direct] / c[incident], std::exp(-tau0 / mu0), 1e-12);
    EXPECT_NEAR(c[absorbed] + c[escaped_direct], c[incident], 1e-12 * c[incident]);
}

// The largest difference of the flux of band q between a and b at cell (i, j, k), any component.
double flux_difference(const ForwardResult& a, const ForwardResult& b, int q, int i, int j, int k) {
    double worst = 0.0;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(a.flux[q](i, j, k, c) - b.flux[q](i, j, k, c)));
    return worst;
}

TEST(Forward, SameSeedSameResultOtherSeedDiffers) {
    Slab slab(MPI_COMM_WORLD, 2.0, 0.95, 0.7);
    const std::vector<DirectionalLight> L{beam(0.8)};
    const ForwardResult a = trace_forward(slab.d, slab.m, L, options(5000, 3));
    const ForwardResult b = trace_forward(slab.d, slab.m, L, options(5000, 3));
    const ForwardResult c = trace_forward(slab.d, slab.m, L, options(5000, 4));
    int same = 1, differs = 0;
    for_each_cell(slab.d.local(), [&](int i, int j, int k) {
        same &= a.fluence[0](i, j, k) == b.fluence[0](i, j, k) && a.fluence_stderr[0](i, j, k) == b.fluence_stderr[0](i, j, k);
        same &= flux_difference(a, b, 0, i, j, k) == 0.0;
        differs |= a.fluence[0](i, j, k) != c.fluence[0](i, j, k);
        differs |= flux_difference(a, c, 0, i, j, k) != 0.0;
    });
    EXPECT_TRUE(same);
    EXPECT_TRUE(differs);
}

// Band 0's fluence, its standard error and the flux of a equal b's to `rel` of b's peak fluence
// on box (the same photons: only the order of the sums may differ; |F| <= fluence).
void expect_same_fields(const ForwardResult& a, const ForwardResult& b, const Box& box, double rel = 1e-12) {
    double worst = 0.0, peak = 0.0, flux = 0.0;
    for_each_cell(box, [&](int i, int j, int k) {
        worst = std::max(worst, std::abs(a.fluence[0](i, j, k) - b.fluence[0](i, j, k)));
        worst = std::max(worst, std::abs(a.fluence_stderr[0](i, j, k) - b.fluence_stderr[0](i, j, k)));
        worst = std::max(worst, flux_difference(a, b, 0, i, j, k));
        peak = std::max(peak, b.fluence[0](i, j, k));
        flux = std::max(flux, std::abs(b.flux[0](i, j, k, 2)));
    });
    EXPECT_GT(flux, 0.0);
    EXPECT_GT(peak, 0.0);
    EXPECT_LE(worst, rel * peak);
}

// Decomposition invariance: the world run equals a run of the whole grid on MPI_COMM_SELF to
// round-off (the batches are the same photons; only the order of the final sums changes).
TEST(Forward, AllRanksMatchOneRank) {
    const std::vector<DirectionalLight> L{beam(0.7), {"sky[0]", normalized(Vec3{0.3, -0.5, -0.6}), {0.4}}};
    Slab world(MPI_COMM_WORLD, 4.0, 0.98, 0.85, {6, 6, 12});
    Slab self(MPI_COMM_SELF, 4.0, 0.98, 0.85, {6, 6, 12});
    const ForwardResult a = trace_forward(world.d, world.m, L, options(8000));
    const ForwardResult b = trace_forward(self.d, self.m, L, options(8000));
    expect_same_fields(a, b, world.d.local());
    EXPECT_EQ(a.photons, b.photons);
    EXPECT_EQ(a.collisions, b.collisions);
    for (int q = 0; q < ncounters; ++q) EXPECT_NEAR(a.counters[0][q], b.counters[0][q], 1e-12 * a.counters[0][incident]);
}

// The batch tallies are folded by following the touched-cell lists or by scanning the grid
// (batch_in_flight.h): each cell's fold is independent of the others', so the fields are
// bit-identical; counters equal to round-off (the total track is summed in the visiting order).
TEST(Forward, FoldingByListOrByScanGivesTheSameFields) {
    const std::vector<DirectionalLight> L{beam(0.7), {"sky[0]", normalized(Vec3{0.3, -0.5, -0.6}), {0.4}}};
    Slab slab(MPI_COMM_WORLD, 3.0, 0.95, 0.6, {8, 8, 12});
    ForwardSettings by_list, by_scan;
    by_list.fold_scan_fraction = 0;
    by_scan.fold_scan_fraction = std::int64_t{1} << 40;
    by_list.tally_reduced = by_scan.tally_reduced = true;
    const ForwardResult a = trace_forward(slab.d, slab.m, L, options(6000), by_list);
    const ForwardResult b = trace_forward(slab.d, slab.m, L, options(6000), by_scan);
    int same = 1;
    double peak = 0.0;
    for_each_cell(slab.d.local(), [&](int i, int j, int k) {
        same &= a.fluence[0](i, j, k) == b.fluence[0](i, j, k) &&
                a.fluence_stderr[0](i, j, k) == b.fluence_stderr[0](i, j, k) &&
                a.reduced[0](i, j, k) == b.reduced[0](i, j, k) && flux_difference(a, b, 0, i, j, k) == 0.0;
        peak = std::max(peak, a.fluence[0](i, j, k));
    });
    EXPECT_GT(peak, 0.0);
    EXPECT_TRUE(same);
    EXPECT_EQ(a.collisions, b.collisions);
    for (int q = 0; q < ncounters; ++q) EXPECT_NEAR(a.counters[0][q], b.counters[0][q], 1e-12 * a.counters[0][incident]);
}

// Terms of one colour (here the two sky terms, proportional in both bands) are traced into the
// same accumulators, each scaled by its power relative to the first, and folded once; the sun
// and a third colour each fold apart. Folded per term instead, every photon and every collision
// is the same, and the fields differ only by rounding.
TEST(Forward, TermsOfOneColourFoldedTogetherGiveTheSameFields) {
    const std::vector<DirectionalLight> L{{"sun", normalized(Vec3{0.2, 0.1, -1.0}), {0.7, 0.5}},
                                          {"sky[0]", normalized(Vec3{0.3, -0.5, -0.6}), {0.4, 0.2}},
                                          {"sky[1]", normalized(Vec3{-0.6, 0.2, -0.4}), {0.1, 0.05}},
                                          {"lamp", normalized(Vec3{0.0, 0.6, -0.5}), {0.3, 0.6}}};
    Slab slab(MPI_COMM_WORLD, 3.0, 0.95, 0.6, {8, 8, 12});
    slab.m.bands.push_back(slab.m.bands[0]);
    slab.m.bands[1].name = "gray2";
    ForwardSettings together, apart;
    apart.fold_by_colour = false;
    together.tally_reduced = apart.tally_reduced = true;
    const ForwardResult a = trace_forward(slab.d, slab.m, L, options(6000), together);
    const ForwardResult b = trace_forward(slab.d, slab.m, L, options(6000), apart);
    EXPECT_EQ(a.collisions, b.collisions);
    for (int band = 0; band < 2; ++band) {
        double peak = 0.0, worst = 0.0;
        for_each_cell(slab.d.local(), [&](int i, int j, int k) { peak = std::max(peak, b.fluence[band](i, j, k)); });
        for_each_cell(slab.d.local(), [&](int i, int j, int k) {
            worst = std::max({worst, std::abs(a.fluence[band](i, j, k) - b.fluence[band](i, j, k)),
                              std::abs(a.fluence_stderr[band](i, j, k) - b.fluence_stderr[band](i, j, k)),
                              std::abs(a.reduced[band](i, j, k) - b.reduced[band](i, j, k)),
                              flux_difference(a, b, band, i, j, k)});
        });
        EXPECT_GT(peak, 0.0);
        EXPECT_LT(worst, 1e-12 * peak) << "band " << band;
        for (int q = 0; q < ncounters; ++q)
            EXPECT_NEAR(a.counters[band][q], b.counters[band][q], 1e-12 * b.counters[band][incident]);
    }
}

// The lane kernel (trace_lanes.h, the default where the CPU has AVX-512) traces the photons the
// scalar kernel traces, on the same paths: the same collisions, the fields and counters to
// round-off, on any rank count.
TEST(Forward, LaneAndScalarKernelsGiveTheSameFields) {
    if (!lane_kernel_supported()) GTEST_SKIP() << "this CPU has no AVX-512: the lane kernel never runs here";
    const std::vector<DirectionalLight> L{beam(0.7), {"sky[0]", normalized(Vec3{0.3, -0.5, -0.6}), {0.4}}};
    Slab slab(MPI_COMM_WORLD, 3.0, 0.95, 0.6, {8, 8, 12});
    MonteCarloOptions scalar = options(6000), lanes = options(6000);
    scalar.kernel = "scalar";
    lanes.kernel = "lanes";
    const ForwardResult a = trace_forward(slab.d, slab.m, L, scalar);
    const ForwardResult b = trace_forward(slab.d, slab.m, L, lanes);
    EXPECT_EQ(a.kernel, "scalar");
    EXPECT_EQ(b.kernel, "lanes");
    EXPECT_EQ(a.collisions, b.collisions);
    EXPECT_EQ(a.segments, b.segments);
    double peak = 0.0, worst = 0.0;
    for_each_cell(slab.d.local(), [&](int i, int j, int k) { peak = std::max(peak, a.fluence[0](i, j, k)); });
    for_each_cell(slab.d.local(), [&](int i, int j, int k) {
        worst = std::max({worst, std::abs(a.fluence[0](i, j, k) - b.fluence[0](i, j, k)),
                          std::abs(a.fluence_stderr[0](i, j, k) - b.fluence_stderr[0](i, j, k)),
                          flux_difference(a, b, 0, i, j, k)});
    });
    EXPECT_GT(peak, 0.0);
    EXPECT_LT(worst, 1e-12 * peak);
    for (int q = 0; q < ncounters; ++q) EXPECT_NEAR(a.counters[0][q], b.counters[0][q], 1e-12 * a.counters[0][incident]);
}

TEST(Forward, ReplicatedMemoryLimitIsACollectiveError) {
    Slab slab(MPI_COMM_WORLD, 1.0, 0.9, 0.0);
    MonteCarloOptions o = options(1000);
    o.max_replicated_memory_gb = 1e-6;
    EXPECT_THROW(trace_forward(slab.d, slab.m, {beam(1.0)}, o), Error);
}

TEST(Forward, StopsAtTargetRelativeError) {
    Slab slab(MPI_COMM_WORLD, 2.0, 0.99, 0.85);
    MonteCarloOptions o = options(2000000);
    o.target_rel_error = 0.05;
    const ForwardResult r = trace_forward(slab.d, slab.m, {beam(1.0)}, o);
    EXPECT_EQ(r.stop_reason, "target_rel_error");
    EXPECT_LT(r.batches, 32);
    EXPECT_LT(r.rel_error, 0.05);
}

// Batches that tally no diffuse power (here a slab of optical depth 1e-12: no photon collides)
// estimate no error: the target is not met by their zero spread (it was, after 8 empty batches),
// the run goes to its photon count, and the error is unknown (NaN), not 0.
TEST(Forward, EmptyTalliesMeetNoTargetAndLeaveTheErrorUnknown) {
    Slab slab(MPI_COMM_WORLD, 1e-12, 0.9, 0.0);
    MonteCarloOptions o = options(64000);
    o.target_rel_error = 0.05;
    const ForwardResult r = trace_forward(slab.d, slab.m, {beam(1.0)}, o);
    EXPECT_EQ(r.collisions, 0);
    EXPECT_EQ(r.stop_reason, "photons");
    EXPECT_EQ(r.batches, o.batches);
    EXPECT_TRUE(std::isnan(r.rel_error));
}

// The target is tested batch by batch from kMinBatchesForTarget on, so the run keeps the same
// first K batches on any rank count (rounds of P batches used to decide per round: 2 batches
// on 1-2 ranks, 12 on 3, fields 4% apart) and never judges from fewer than 8 batches.
TEST(Forward, TargetRelativeErrorStopIsTheSameOnAnyRankCount) {
    Slab world(MPI_COMM_WORLD, 2.0, 0.99, 0.85);
    Slab self(MPI_COMM_SELF, 2.0, 0.99, 0.85);
    MonteCarloOptions o = options(640000);
    o.target_rel_error = 0.5;  // met by any two batches: the minimum decides
    const ForwardResult a = trace_forward(world.d, world.m, {beam(1.0)}, o);
    const ForwardResult b = trace_forward(self.d, self.m, {beam(1.0)}, o);
    EXPECT_EQ(a.stop_reason, "target_rel_error");
    EXPECT_EQ(a.batches, mc::kMinBatchesForTarget);
    EXPECT_EQ(b.batches, a.batches);
    EXPECT_EQ(b.photons, a.photons);
    expect_same_fields(a, b, world.d.local());
}

// A run on the test slab of `batches` batches of `per_batch` photons under time_budget `budget`.
ForwardResult budget_run(const Slab& slab, int batches, std::int64_t per_batch, double budget) {
    MonteCarloOptions o = options(batches * per_batch);
    o.batches = batches;
    o.time_budget = budget;
    return trace_forward(slab.d, slab.m, {beam(0.8)}, o);
}

// r (a budget run of one light term) equals a budget-free run of the photons and batches it
// reports: the same photons, so the same fields, counters and standard errors to round-off, the
// same collisions. (With several terms the per-term rounding of the total may differ.)
void expect_equals_budget_free_run(const Slab& slab, const ForwardResult& r) {
    MonteCarloOptions same = options(r.photons);
    same.batches = r.batches;
    const ForwardResult e = trace_forward(slab.d, slab.m, {beam(0.8)}, same);
    EXPECT_EQ(e.stop_reason, "photons");
    EXPECT_EQ(e.layout_batches, r.batches);
    EXPECT_EQ(e.photons, r.photons);
    EXPECT_EQ(e.collisions, r.collisions);
    // A budget run traces its batches in chunks, and at a chunk's end the lane kernel drains and
    // refills its lanes, so a cell's tallies are added in another order than in one piece: up
    // to 1.8e-12 of the peak when a loaded machine made the chunks short (1e-12 failed then).
    // One photon more or less moves the peak cell by ~1e-6 of it, five orders above this bound.
    expect_same_fields(r, e, slab.d.local(), 1e-11);
    const Counters& c = r.counters[0];
    for (int q = 0; q < ncounters; ++q) {
        EXPECT_NEAR(c[q], e.counters[0][q], 1e-12 * c[incident]);
        EXPECT_NEAR(r.counters_stderr[0][q], e.counters_stderr[0][q], 1e-12 * c[incident]);
    }
    EXPECT_NEAR(r.rel_error, e.rel_error, 1e-12);
}

// model.montecarlo.time_budget with far more photons than fit (the whole run, 8 x 10^7 photons,
// would take minutes) in short batches (the pilot keeps them): the run stops at the budget,
// dropping the batches the deadline cut, so within the budget plus a margin and after most of
// it, with stop_reason "time_budget". The result is that of the batches it completed: equal to
// round-off to a run of exactly those photons without a budget (so normalized like any run),
// with the energy balance closed.
TEST(Forward, StopsAtTheTimeBudget) {
    constexpr int kBatches = 4096;
    constexpr std::int64_t kPerBatch = 20000;  // ~30 ms per batch on one core
    constexpr double kBudget = 0.5;            // s
    Slab slab(MPI_COMM_WORLD, 2.0, 0.99, 0.85);
    const ForwardResult r = budget_run(slab, kBatches, kPerBatch, kBudget);
    EXPECT_EQ(r.stop_reason, "time_budget");
    EXPECT_EQ(r.layout_batches, kBatches);
    EXPECT_GE(r.batches, 2);
    EXPECT_LT(r.batches, kBatches / 4);
    EXPECT_EQ(r.photons, r.batches * kPerBatch);
    EXPECT_LT(r.seconds, 2.0 * kBudget);
    EXPECT_GT(r.seconds, 0.5 * kBudget);
    if (test::world_rank() == 0)
        std::printf("    budget %.2f s: %d batches, %.3f s (tracing %.3f s)\n", kBudget, r.batches, r.seconds,
                    r.trace_seconds);

    expect_equals_budget_free_run(slab, r);
    const Counters& c = r.counters[0];
    EXPECT_NEAR(c[incident], 0.8 * 64.0, 1e-9);
    double escaped = c[escaped_direct];
    for (int f = 0; f < 6; ++f) escaped += c[escaped_xlo + f];
    EXPECT_NEAR(c[absorbed] + escaped - c[roulette_net], c[incident], 1e-12 * c[incident]);
    EXPECT_NEAR(c[absorbed] + escaped, c[incident], 1e-3 * c[incident]);
}

// Batches shorter than a chunk (1.5 ms against 6 ms: each is traced in one piece): the budget
// is still kept, the deadline checked after every round as well as within a batch.
TEST(Forward, StopsAtTheTimeBudgetWithBatchesShorterThanAChunk) {
    constexpr int kBatches = 4096;
    constexpr std::int64_t kPerBatch = 1000;
    constexpr double kBudget = 0.3;  // s; all 4096 batches would take ~6 s
    Slab slab(MPI_COMM_WORLD, 2.0, 0.99, 0.85);
    const ForwardResult r = budget_run(slab, kBatches, kPerBatch, kBudget);
    EXPECT_EQ(r.stop_reason, "time_budget");
    EXPECT_EQ(r.layout_batches, kBatches);
    EXPECT_LT(r.batches, kBatches / 4);
    EXPECT_EQ(r.photons, r.batches * kPerBatch);
    EXPECT_LT(r.seconds, kBudget + 0.2);
    EXPECT_GT(r.seconds, 0.75 * kBudget);
}

// A photon count whose first batch alone takes far longer than the budget (32 batches of 2^22
// photons, ~6 s each on one core, against a 0.6 s budget; before the pilot the first round
// always completed, 6 s on 2 ranks, 12 s on 1): the pilot splits the batches by a power of two,
// and the run stops within the budget plus a small margin. What it keeps is a prefix of the
// split layout, so a budget-free run of the photons and batches it reports traces the same
// photons: the same fields, counters and standard errors to round-off, the same collisions.
TEST(Forward, TimeBudgetHoldsWhenOneBatchIsFarLonger) {
    constexpr int kBatches = 32;
    constexpr std::int64_t kPerBatch = std::int64_t{1} << 22;
    constexpr double kBudget = 0.6;  // s
    constexpr double kMargin =
        0.2;  // s: one chunk (12 ms here), the final reduction, a busy machine
    Slab slab(MPI_COMM_WORLD, 2.0, 0.99, 0.85);
    const ForwardResult r = budget_run(slab, kBatches, kPerBatch, kBudget);
    EXPECT_EQ(r.stop_reason, "time_budget");
    EXPECT_LT(r.seconds, kBudget + kMargin);
    EXPECT_GT(r.seconds, 0.75 * kBudget);
    const int split = r.layout_batches / kBatches;
    EXPECT_EQ(r.layout_batches, split * kBatches);
    EXPECT_GT(split, 1);
    EXPECT_EQ(split & (split - 1), 0);  // a power of two
    const std::int64_t per_batch = kPerBatch / split;
    EXPECT_GE(r.batches, 2);
    EXPECT_EQ(r.photons, r.batches * per_batch);
    EXPECT_LT(r.photons, kPerBatch);  // less than one batch of the layout asked for
    if (test::world_rank() == 0)
        std::printf(
            "    budget %.2f s, %lld photons asked: %d batches of %lld photons (split %d), %.3f "
            "s\n",
            kBudget, static_cast<long long>(kBatches * kPerBatch), r.batches,
            static_cast<long long>(per_batch), split, r.seconds);
    expect_equals_budget_free_run(slab, r);
}

// The pilot's choice (batch_split): keep the batches when all or enough of them fit; otherwise
// halve them until the batch count asked for (and a round to spare) fits, but not below
// kMinBatchSeconds a batch, nor past a photon of every term per batch.
TEST(Forward, BatchSplitFitsTheBatchesAskedForInTheBudget) {
    constexpr std::int64_t kAny = std::int64_t{1} << 30;
    EXPECT_EQ(batch_split(0.1, 10.0, 32, 2, kAny), 1);  // all 16 rounds fit
    EXPECT_EQ(batch_split(0.03, 0.48, 4096, 1, kAny),
              1);  // 16 of 4096 fit: enough (StopsAtTheTimeBudget)
    EXPECT_EQ(batch_split(0.0, 1.0, 32, 1, kAny), 1);  // no estimate (a rank with nothing to trace)
    // 8 s batches, 20 s left, 1 rank: 33 rounds need batches of 1/13.2; by 16, 40 rounds fit
    EXPECT_EQ(batch_split(8.0, 20.0, 32, 1, kAny), 16);
    EXPECT_EQ(batch_split(8.0, 20.0, 32, 4, kAny), 1);  // 4 ranks: 2 rounds, 8 batches fit: enough
    EXPECT_EQ(batch_split(8.0, 12.0, 32, 4, kAny),
              8);  // 1 round fits; 9 rounds need 1/6; by 8, 12 fit
    // 2 s batches, 0.95 s left: 33 rounds would need 1/70, but 2 s / 64 = 31 ms < kMinBatchSeconds
    EXPECT_EQ(batch_split(2.0, 0.95, 32, 1, kAny), 32);
    EXPECT_EQ(batch_split(1.0, -0.5, 32, 1, kAny), 16);  // the budget is gone: the shortest batches
    EXPECT_EQ(batch_split(8.0, 20.0, 32, 1, 100),
              2);  // 64 batches <= 100 photons of a term; 128 not
    EXPECT_EQ(batch_split(1.0, 2.5, 4, 1, kAny), 2);  // 2 of 4 fit (< 4): 5 rounds of 0.5 s
}

// The progress line's ETA is the time to the earliest stop that applies: the photon count, what
// is left of the time budget, or the target error at rel_error ∝ 1/sqrt(batches).
TEST(Forward, EtaIsTheEarliestStop) {
    MonteCarloOptions o = options(1000000);
    o.batches = 100;
    // 10 batches in 1 s: 90 more at 0.1 s each
    StopEta e = eta_to_stop(o, 10, 1.0, 1.2, 0.02);
    EXPECT_NEAR(e.seconds, 9.0, 1e-12);
    EXPECT_EQ(e.until, "photon count");
    // the log this fixes: 2.2% done after 2 s, ETA 89 s, with a 3 s budget; now 1 s
    o.time_budget = 3.0;
    e = eta_to_stop(o, 10, 1.8, 2.0, 0.02);
    EXPECT_NEAR(e.seconds, 1.0, 1e-12);
    EXPECT_EQ(e.until, "time budget");
    e = eta_to_stop(o, 10, 1.8, 3.5, 0.02);  // past the budget (a round overran it): 0
    EXPECT_EQ(e.seconds, 0.0);
    // target 0.01 from 0.02 after 10 batches: 4x the batches, 30 more at 0.1 s
    o.time_budget = 0.0;
    o.target_rel_error = 0.01;
    e = eta_to_stop(o, 10, 1.0, 1.2, 0.02);
    EXPECT_NEAR(e.seconds, 3.0, 1e-12);
    EXPECT_EQ(e.until.rfind("target error", 0), 0u);
    o.time_budget = 3.0;  // the budget ends first (1.8 s left)
    EXPECT_EQ(eta_to_stop(o, 10, 1.0, 1.2, 0.02).until, "time budget");
    o.time_budget = 0.0;  // reached: 0; no estimate yet (rel_error 0): the photon count
    EXPECT_EQ(eta_to_stop(o, 10, 1.0, 1.2, 0.005).seconds, 0.0);
    EXPECT_EQ(eta_to_stop(o, 10, 1.0, 1.2, 0.0).until, "photon count");
    o.target_rel_error = 0.001;  // beyond the photon count: the photon count
    EXPECT_EQ(eta_to_stop(o, 10, 1.0, 1.2, 0.02).until, "photon count");
    // Met already after 2 batches, but the target is tested from the 8th: 6 more at 0.1 s.
    o.target_rel_error = 0.01;
    e = eta_to_stop(o, 2, 0.2, 0.3, 0.005);
    EXPECT_NEAR(e.seconds, 0.6, 1e-12);
    EXPECT_EQ(e.until.rfind("target error", 0), 0u);
}

}  // namespace
}  // namespace nimbus::mc
