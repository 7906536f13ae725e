// Volume emission in the forward Monte Carlo (solvers/montecarlo/emitter.h, [[sources]]):
//   (a) energy balance: absorbed + escaped = emitted (+ the roulette's net weight, exactly),
//       and the track-length fluence gives the same absorption, sigma_a ∫ phi dV, as the
//       collision counter (two estimators of one number, z-test);
//   (b) infinite medium: a uniform source q = P/4π in a cube 48 mean free paths across: the
//       centre fluence is 4π q / (kappa (1 - a)) = P / (kappa (1 - a)) (z-test per cell);
//   (c) one emitting cell in a pure absorber: the cell-averaged fluence at distance r is
//       P exp(-kappa r) / (4π r²) integrated over the source cell and averaged over the
//       detector cell (6-D Gauss-Legendre), z-test per detector;
//   (d) the same seed gives the same result (fluence and flux) on 1 rank (MPI_COMM_SELF) and
//       on all ranks, with a light and two sources sharing the photon budget;
//   (e) the void duct (scenes/duct.toml): a short run with another seed agrees with the stored
//       reference that the DOM test compares against (tests/data/duct_mc_reference.csv).
#include "src/scene/emission.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "solvers/montecarlo/forward.h"
#include "tests/support/duct_reference.h"
#include "tests/support/mpi_test.h"
#include "tests/support/point_source.h"

namespace nimbus::mc {
namespace {

// A homogeneous cube (no periodic axes) of n cells of edge h, density 1.
struct Cube {
    Decomposition d;
    Medium m;
    Cube(MPI_Comm comm, Int3 n, double h, BandOptics optics)
        : d(comm, n, {0, 0, 0}, {false, false, false}) {
        m.grid.n = n;
        m.grid.h = h;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = 1.0; });
        m.bands = {optics};
    }
};

MonteCarloOptions options(std::int64_t photons, std::uint64_t seed = 11) {
    MonteCarloOptions o;
    o.photons = photons;
    o.seed = seed;
    o.batches = 32;
    return o;
}

double escaped(const Counters& c) {
    double e = c[escaped_direct];
    for (int f = 0; f < 6; ++f) e += c[escaped_xlo + f];
    return e;
}

// Sum over the ranks of f(i, j, k) over the owned cells.
template <class F>
double world_sum(const Decomposition& d, F&& f) {
    double s = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) { s += f(i, j, k); });
    MPI_Allreduce(MPI_IN_PLACE, &s, 1, MPI_DOUBLE, MPI_SUM, d.comm());
    return s;
}

TEST(Emission, EnergyBalance) {
    // 10^3 cells of 0.5 m, kappa 1.2 /m, a 0.8, g 0.5; a source of 3 W/m³ in a 4x3x5 box off centre.
    Cube c(MPI_COMM_WORLD, {10, 10, 10}, 0.5, BandOptics{"gray", 1.2, 0.8, 0.5});
    const std::vector<VolumeSource> src{{Box{{2, 4, 1}, {6, 7, 6}}, {3.0}}};
    const ForwardResult r = trace_forward(c.d, c.m, {}, src, options(200000));
    const Counters& k = r.counters[0];
    const double P = 3.0 * 4 * 3 * 5 * std::pow(0.5, 3);
    EXPECT_NEAR(k[emitted], P, 1e-12 * P);
    EXPECT_EQ(k[incident], 0.0);
    EXPECT_EQ(k[escaped_direct], 0.0);  // emitted light is diffuse (escaped_xlo..zhi)
    // Every photon's weight ends absorbed, escaped or removed by roulette: exact.
    EXPECT_NEAR(k[absorbed] + escaped(k) - k[roulette_net], P, 1e-12 * P);
    // The roulette's net weight is zero on average: the balance holds to 1e-3 without it.
    const double balance = (k[absorbed] + escaped(k) - P) / P;
    // Absorption from the track-length fluence, sigma_a ∫ phi dV, against the collision counter.
    // The two are correlated (same photons), so the z from independent errors is conservative.
    const double sigma_a = 1.2 * (1.0 - 0.8), V = std::pow(0.5, 3);
    const double fluence_integral =
        world_sum(c.d, [&](int i, int j, int k3) { return V * r.fluence[0](i, j, k3); });
    EXPECT_NEAR(fluence_integral, k[diffuse_volume], 1e-9 * k[diffuse_volume]);
    const double track_abs = sigma_a * k[diffuse_volume];
    const double z =
        (track_abs - k[absorbed]) /
        std::hypot(sigma_a * r.counters_stderr[0][diffuse_volume], r.counters_stderr[0][absorbed]);
    if (test::world_rank() == 0)
        std::printf(
            "emission balance: emitted %.6f W, (absorbed + escaped - emitted)/emitted %.2e, "
            "roulette %.2e, "
            "sigma_a∫phi %.6f vs absorbed %.6f (z %.2f)\n",
            P, balance, k[roulette_net] / P, track_abs, k[absorbed], z);
    EXPECT_LT(std::abs(balance), 1e-3);
    EXPECT_LT(std::abs(z), 4.0);
}

TEST(Emission, InfiniteMediumCentreFluence) {
    // 12^3 cells with kappa h = 4 (48 mfp across), a 0.5, g 0.3: the centre 4^3 cells are 16 mfp
    // from every face (the boundary's influence there is below e^-16 ~ 1e-7), so their fluence is
    // the infinite-medium P / (kappa (1 - a)) to 1e-3 and better.
    const double h = 0.25, kappa = 16.0, a = 0.5, P = 2.0;
    Cube c(MPI_COMM_WORLD, {12, 12, 12}, h, BandOptics{"gray", kappa, a, 0.3});
    const std::vector<VolumeSource> src{{Box{{0, 0, 0}, {12, 12, 12}}, {P}}};
    const ForwardResult r = trace_forward(c.d, c.m, {}, src, options(1200000));
    const double exact = P / (kappa * (1.0 - a));
    double z2 = 0.0, zmax = 0.0, dev = 0.0, count = 0.0, se = 0.0;
    const Box centre{{4, 4, 4}, {8, 8, 8}};
    for_each_cell(centre.intersect(c.d.local()), [&](int i, int j, int k) {
        const double z = (r.fluence[0](i, j, k) - exact) / r.fluence_stderr[0](i, j, k);
        z2 += z * z;
        zmax = std::max(zmax, std::abs(z));
        dev += r.fluence[0](i, j, k) - exact;
        se += r.fluence_stderr[0](i, j, k) * r.fluence_stderr[0](i, j, k);
        count += 1.0;
    });
    double v[4] = {z2, dev, count, se};
    MPI_Allreduce(MPI_IN_PLACE, v, 4, MPI_DOUBLE, MPI_SUM, c.d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &zmax, 1, MPI_DOUBLE, MPI_MAX, c.d.comm());
    const double rms = std::sqrt(v[0] / v[2]), mean_dev = v[1] / v[2] / exact;
    const double mean_se = std::sqrt(v[3]) / v[2] / exact;  // as if the cells were independent
    if (test::world_rank() == 0)
        std::printf(
            "infinite medium: exact %.6f, centre mean rel. deviation %+.2e (se %.1e), rms z %.2f, "
            "max |z| %.2f\n",
            exact, mean_dev, mean_se, rms, zmax);
    EXPECT_EQ(v[2], 64.0);
    // rms z near 1 both ways: below, the standard errors would be too large (they would hide a bias)
    EXPECT_GT(rms, 0.6);
    EXPECT_LT(rms, 1.4);
    EXPECT_LT(zmax, 4.5);
    EXPECT_LT(std::abs(mean_dev), 4.0 * mean_se + 1e-3);
}

TEST(Emission, PointSourceInAPureAbsorber) {
    // 15^3 cells of 1 m, kappa 0.3 /m, a = 0; one emitting cell at (7, 7, 7) of 5 W/m³ (P = 5 W).
    const double h = 1.0, kappa = 0.3, p = 5.0;
    Cube c(MPI_COMM_WORLD, {15, 15, 15}, h, BandOptics{"gray", kappa, 0.0, 0.0});
    const std::vector<VolumeSource> src{{Box{{7, 7, 7}, {8, 8, 8}}, {p}}};
    const ForwardResult r = trace_forward(c.d, c.m, {}, src, options(800000));
    const std::vector<Int3> detectors = {{9, 7, 7},  {10, 7, 7}, {11, 7, 7}, {13, 7, 7},
                                         {7, 4, 7},  {7, 7, 2},  {9, 9, 7},  {10, 10, 10},
                                         {5, 9, 11}, {3, 3, 3}};
    double z2 = 0.0, zmax = 0.0;
    for (const Int3& q : detectors) {
        double v[2] = {0.0, 0.0};
        if (c.d.local().contains(q[0], q[1], q[2]))
            v[0] = r.fluence[0](q[0], q[1], q[2]), v[1] = r.fluence_stderr[0](q[0], q[1], q[2]);
        MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_SUM, c.d.comm());
        const double exact = test::point_source_fluence(
            {7, 7, 7}, {double(q[0]), double(q[1]), double(q[2])}, h, kappa, p * h * h * h);
        const double z = (v[0] - exact) / v[1];
        if (test::world_rank() == 0)
            std::printf(
                "point source: cell (%d,%d,%d) r %.2f m: MC %.5e ± %.1e, exact %.5e (rel %+.3f, z "
                "%+.2f)\n",
                q[0], q[1], q[2], std::hypot(q[0] - 7.0, q[1] - 7.0, q[2] - 7.0), v[0], v[1], exact,
                v[0] / exact - 1.0, z);
        z2 += z * z;
        zmax = std::max(zmax, std::abs(z));
    }
    // 10 detectors: rms z within [0.5, 1.6] (chi-square with 10 degrees of freedom puts 99% of
    // rms values above 0.51; standard errors twice too large would give ~0.4)
    const double rms = std::sqrt(z2 / static_cast<double>(detectors.size()));
    EXPECT_GT(rms, 0.5);
    EXPECT_LT(rms, 1.6);
    EXPECT_LT(zmax, 4.0);
    // Energy: a pure absorber absorbs at the first collision; every photon's weight is absorbed or escapes.
    const Counters& k = r.counters[0];
    EXPECT_NEAR(k[absorbed] + escaped(k), k[emitted], 1e-12 * k[emitted]);
    EXPECT_EQ(k[roulette_net], 0.0);
}

// Decomposition invariance with a light and two sources (one in a band ratio of its own).
struct Scene2 {
    Decomposition d;
    Medium m;
    Scene2(MPI_Comm comm) : d(comm, {8, 6, 10}, {0, 0, 0}, {false, false, false}) {
        m.grid.n = {8, 6, 10};
        m.grid.h = 0.5;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            m.rho(i, j, k) = (i + j + k) % 4 == 0 ? 0.0 : 0.5 + 0.1 * (k % 3);
        });
        m.bands = {BandOptics{"r", 1.1, 0.9, 0.6}, BandOptics{"g", 1.1, 0.9, 0.6}};
    }
};

TEST(Emission, AllRanksMatchOneRankAndSameSeedSameResult) {
    const std::vector<DirectionalLight> L{{"sun", normalized(Vec3{0.2, 0.3, -1.0}), {1.0, 0.7}}};
    const std::vector<VolumeSource> S{{Box{{1, 1, 1}, {4, 3, 6}}, {2.0, 0.5}},
                                      {Box{{5, 2, 6}, {8, 6, 10}}, {0.3, 3.0}}};
    Scene2 world(MPI_COMM_WORLD), self(MPI_COMM_SELF);
    const ForwardResult a = trace_forward(world.d, world.m, L, S, options(20000));
    const ForwardResult a2 = trace_forward(world.d, world.m, L, S, options(20000));
    const ForwardResult b = trace_forward(self.d, self.m, L, S, options(20000));
    double worst = 0.0, peak = 0.0;
    int same = 1;
    for (int q = 0; q < 2; ++q)
        for_each_cell(world.d.local(), [&](int i, int j, int k) {
            worst = std::max(worst, std::abs(a.fluence[q](i, j, k) - b.fluence[q](i, j, k)));
            worst = std::max(worst,
                             std::abs(a.fluence_stderr[q](i, j, k) - b.fluence_stderr[q](i, j, k)));
            peak = std::max(peak, b.fluence[q](i, j, k));
            same &= a.fluence[q](i, j, k) == a2.fluence[q](i, j, k);
            for (int c = 0; c < 3; ++c) {  // the flux too (|F| <= fluence)
                worst = std::max(worst, std::abs(a.flux[q](i, j, k, c) - b.flux[q](i, j, k, c)));
                same &= a.flux[q](i, j, k, c) == a2.flux[q](i, j, k, c);
            }
        });
    EXPECT_TRUE(same);
    EXPECT_GT(peak, 0.0);
    EXPECT_LE(worst, 1e-12 * peak);
    EXPECT_EQ(a.photons, b.photons);
    EXPECT_EQ(a.collisions, b.collisions);
    for (int q = 0; q < 2; ++q) {
        const Counters& k = a.counters[static_cast<size_t>(q)];
        EXPECT_GT(k[incident], 0.0);
        EXPECT_GT(k[emitted], 0.0);
        for (int c = 0; c < ncounters; ++c)
            EXPECT_NEAR(k[c], b.counters[static_cast<size_t>(q)][c], 1e-12 * k[emitted]);
        EXPECT_NEAR(k[absorbed] + escaped(k) - k[roulette_net], k[incident] + k[emitted],
                    1e-12 * (k[incident] + k[emitted]));
    }
}

TEST(Emission, ABandWithoutPowerStaysDark) {
    // Two bands with different optics (traced separately); the source emits only in band 0.
    Cube c(MPI_COMM_WORLD, {6, 6, 6}, 1.0, BandOptics{"r", 0.5, 0.9, 0.0});
    c.m.bands.push_back(BandOptics{"b", 0.8, 0.5, 0.3});
    const ForwardResult r =
        trace_forward(c.d, c.m, {}, {{Box{{1, 1, 1}, {4, 4, 4}}, {2.0, 0.0}}}, options(20000));
    EXPECT_EQ(world_sum(c.d, [&](int i, int j, int k) { return r.fluence[1](i, j, k); }), 0.0);
    EXPECT_GT(world_sum(c.d, [&](int i, int j, int k) { return r.fluence[0](i, j, k); }), 0.0);
    EXPECT_EQ(r.counters[1][emitted], 0.0);
    EXPECT_NEAR(r.counters[0][emitted], 2.0 * 27, 1e-12);
    EXPECT_EQ(r.photons, 20000);
}

TEST(Emission, VoidDuctAgreesWithTheStoredReference) {
    const auto ref = test::read_duct_reference();
    ASSERT_EQ(ref.size(), 3u) << "missing tests/data/duct_mc_reference.csv";
    test::DuctWorld w(MPI_COMM_WORLD);
    const std::vector<VolumeSource> src = volume_sources(w.scene);
    const ForwardResult r =
        trace_forward(w.d, w.m, {}, src, options(400000, 7));  // the reference used seed 2026
    for (const auto& [name, cells] : ref) {
        double v[3] = {0, 0, 0}, zmax = 0;  // Σ z², count, Σ (mc - ref) / Σ ref numerator
        double sum_ref = 0;
        for (const auto& [c, rc] : cells) {
            sum_ref += rc.mean;
            if (!w.d.local().contains(c[0], c[1], c[2])) continue;
            const double e = r.fluence[0](c[0], c[1], c[2]) - rc.mean;
            const double z = e / std::hypot(r.fluence_stderr[0](c[0], c[1], c[2]), rc.se);
            v[0] += z * z, v[1] += 1, v[2] += e;
            zmax = std::max(zmax, std::abs(z));
        }
        MPI_Allreduce(MPI_IN_PLACE, v, 3, MPI_DOUBLE, MPI_SUM, w.d.comm());
        MPI_Allreduce(MPI_IN_PLACE, &zmax, 1, MPI_DOUBLE, MPI_MAX, w.d.comm());
        const double rms = std::sqrt(v[0] / v[1]);
        if (test::world_rank() == 0)
            std::printf(
                "duct %-6s %3.0f cells: MC (400k photons) vs stored reference: rms z %.2f, max |z| "
                "%.2f, bias %+.4f\n",
                name.c_str(), v[1], rms, zmax, v[2] / sum_ref);
        EXPECT_GT(rms, 0.6) << name;  // standard errors not inflated (they would hide a bias)
        EXPECT_LT(rms, 1.4) << name;
        EXPECT_LT(zmax, 4.5) << name;
    }
}

}  // namespace
}  // namespace nimbus::mc
