// The Monte Carlo diffuse flux F = ∫ I_d w dw (ForwardResult::flux, the model's flux_diffuse):
// cell mean per band, W/m², normalized as fluence_diffuse.
//   (a) a conservative slab (albedo 1) periodic in x and y under an overhead sun: F_x = F_y = 0
//       by symmetry, and dF_z/dz = Q (the first-scatter power density), so
//         F_z(z) = -E0 mu0 t + E0 mu0 (exp(-kappa (H - z) / mu0) - exp(-tau0 / mu0)),
//       t the diffuse transmission of the independent slab reference (tests/support): every
//       layer's mean F_z against its exact mean;
//   (b) an absorbing slab under an oblique sun: the energy balance dF_z/dz = Q - sigma_a phi,
//       integrated against z and H - z over the slab, ties ∫ F_z dz to the reflected (top) and
//       transmitted (bottom) diffuse counters and the fluence tally; F_y = 0 by symmetry; F_x > 0
//       (the light scattered forward keeps drifting along the sun's +x);
//   (c) one emitting cell in a pure absorber: F at distance r is P exp(-kappa r) r̂ / (4π r²),
//       integrated over the source and detector cells (the emission test's quadrature with r̂),
//       per detector and component; an emitted photon's flux is tallied from its start.
// The estimator is the collision estimator (photon.h): each collision that ends a diffuse
// flight adds w P d / (kappa V) (the model's default kernel, lanes where the CPU has AVX-512;
// lanes_test.cpp ties the scalar kernel to it). F has no standard error, so (a) and (b) repeat
// the run with K seeds and t-test the mean of the K values; in (c) every photon collides at
// most once, with weight 1, so Var F_a <= P phi / (N kappa V) (phi = P E[1_coll] / (kappa V))
// bounds it.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "solvers/montecarlo/forward.h"
#include "src/scene/emission.h"
#include "tests/support/mpi_test.h"
#include "tests/support/slab_reference.h"

namespace nimbus::mc {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kNz = 32;

// A homogeneous slab of 8 x 8 x kNz cells of edge h (not 1 m, so that a lost h² shows),
// periodic in x and y, density 1, optical thickness tau0.
struct Slab {
    Decomposition d;
    Medium m;
    double h, kappa, H;
    Slab(double tau0, double albedo, double g, double h_)
        : d(MPI_COMM_WORLD, {8, 8, kNz}, {0, 0, 0}, {true, true, false}), h(h_), H(kNz * h_) {
        m.grid.n = {8, 8, kNz};
        m.grid.h = h;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = 1.0; });
        kappa = tau0 / H;
        m.bands = {BandOptics{"gray", kappa, albedo, g}};
    }
    double area() const { return 64.0 * h * h; }
};

// One run's layer means (over the 64 cells of each layer, all ranks) of F_x, F_y, F_z and the
// fluence, and the reflected and transmitted diffuse counters per unit area.
struct SlabRun {
    std::array<std::array<double, kNz>, 4> layer{};  // [F_x, F_y, F_z, phi][k]
    double R = 0.0, T = 0.0;                         // W/m²
};

SlabRun run_slab(const Slab& s, const DirectionalLight& sun, std::int64_t photons,
                 std::uint64_t seed) {
    MonteCarloOptions o;
    o.photons = photons;
    o.seed = seed;
    o.batches = 8;
    const ForwardResult r = trace_forward(s.d, s.m, {sun}, o);
    SlabRun out;
    for_each_cell(s.d.local(), [&](int i, int j, int k) {
        for (int a = 0; a < 3; ++a)
            out.layer[static_cast<size_t>(a)][static_cast<size_t>(k)] +=
                r.flux[0](i, j, k, a) / 64.0;
        out.layer[3][static_cast<size_t>(k)] += r.fluence[0](i, j, k) / 64.0;
    });
    MPI_Allreduce(MPI_IN_PLACE, out.layer.data(), 4 * kNz, MPI_DOUBLE, MPI_SUM, s.d.comm());
    out.R = r.counters[0][escaped_zhi] / s.area();
    out.T = r.counters[0][escaped_zlo] / s.area();
    return out;
}

// Mean and standard error of the mean of K values.
struct MeanSe {
    double mean = 0.0, se = 0.0;
};
MeanSe mean_se(const std::vector<double>& v) {
    MeanSe m;
    for (const double x : v) m.mean += x;
    m.mean /= static_cast<double>(v.size());
    double ss = 0.0;
    for (const double x : v) ss += (x - m.mean) * (x - m.mean);
    m.se = std::sqrt(ss / (static_cast<double>(v.size()) * (static_cast<double>(v.size()) - 1.0)));
    return m;
}

// The K runs' values of each quantity of `value(run)` (a vector of quantities per run).
template <class Value>
std::vector<MeanSe> over_runs(const std::vector<SlabRun>& runs, Value&& value) {
    std::vector<std::vector<double>> per_quantity;
    for (const SlabRun& r : runs) {
        const std::vector<double> v = value(r);
        per_quantity.resize(v.size());
        for (size_t q = 0; q < v.size(); ++q) per_quantity[q].push_back(v[q]);
    }
    std::vector<MeanSe> out;
    for (const std::vector<double>& v : per_quantity) out.push_back(mean_se(v));
    return out;
}

constexpr int kRuns = 32;  // t-values with 31 degrees of freedom
constexpr std::int64_t kPhotonsPerRun = 20000;

// t-values of layer means against expected values: none beyond 5 (t_31: two-sided p = 2e-5
// each, so under 0.2% for 3 x 32 values). No bound on their RMS: the layers' errors are
// strongly correlated (a path crosses many layers; in the conservative slab every layer's F_z
// moves with the transmission), so the RMS fluctuates like a single |t|.
void expect_t_values(const std::vector<MeanSe>& got, const std::vector<double>& expect,
                     const char* what) {
    SCOPED_TRACE(what);
    double t2 = 0.0, tmax = 0.0;
    for (size_t k = 0; k < got.size(); ++k) {
        const double t = (got[k].mean - expect[k]) / got[k].se;
        t2 += t * t;
        tmax = std::max(tmax, std::abs(t));
    }
    const double rms = std::sqrt(t2 / static_cast<double>(got.size()));
    if (test::world_rank() == 0) std::printf("    %s: t rms %.3f, max |t| %.2f\n", what, rms, tmax);
    EXPECT_LT(tmax, 5.0);
}

TEST(Flux, ConservativeSlabUnderAnOverheadSunMatchesTheReference) {
    const double tau0 = 4.0, g = 0.85, mu0 = 1.0, E0 = 1.0;
    const Slab s(tau0, 1.0, g, 0.5);
    const DirectionalLight sun{"sun", {0.0, 0.0, -1.0}, {E0}};
    std::vector<SlabRun> runs;
    for (int r = 0; r < kRuns; ++r)
        runs.push_back(run_slab(s, sun, kPhotonsPerRun, 100 + static_cast<std::uint64_t>(r)));

    test::SlabProblem p{tau0, 1.0, g, mu0};
    const test::SlabSolution ref = test::solve_slab(p);
    // The exact layer means: F_z(z) = E0 mu0 (-t + exp(-kappa (H - z) / mu0) - exp(-tau0 / mu0)).
    std::vector<double> fz(kNz), zero(kNz, 0.0);
    for (int k = 0; k < kNz; ++k) {
        const double mean_exp = mu0 / (s.kappa * s.h) *
                                (std::exp(-s.kappa * (s.H - (k + 1) * s.h) / mu0) -
                                 std::exp(-s.kappa * (s.H - k * s.h) / mu0));
        fz[static_cast<size_t>(k)] =
            E0 * mu0 * (-ref.transmitted_diffuse + mean_exp - std::exp(-tau0 / mu0));
    }
    for (int a = 0; a < 3; ++a) {
        const std::vector<MeanSe> got = over_runs(runs, [&](const SlabRun& r) {
            return std::vector<double>(r.layer[static_cast<size_t>(a)].begin(),
                                       r.layer[static_cast<size_t>(a)].end());
        });
        expect_t_values(got, a == 2 ? fz : zero,
                        a == 0 ? "F_x = 0" : (a == 1 ? "F_y = 0" : "F_z against the reference"));
        if (a == 2 && test::world_rank() == 0)
            std::printf(
                "    F_z top layer %.5f ± %.5f (exact %.5f), bottom %.5f ± %.5f (exact %.5f) "
                "W/m²\n",
                got[kNz - 1].mean, got[kNz - 1].se, fz[kNz - 1], got[0].mean, got[0].se, fz[0]);
    }
    // The run is the reference's slab: its reflected diffuse counter agrees with the reference.
    std::vector<double> R;
    for (const SlabRun& r : runs) R.push_back(r.R);
    const MeanSe Rm = mean_se(R);
    EXPECT_LT(std::abs(Rm.mean - E0 * mu0 * ref.reflected), 5.0 * Rm.se);
}

TEST(Flux, AbsorbingSlabUnderAnObliqueSunBalancesEnergy) {
    const double tau0 = 2.0, albedo = 0.9, g = 0.85, mu0 = 0.5, E0 = 1.0;
    const Slab s(tau0, albedo, g, 0.5);
    const DirectionalLight sun{"sun", {std::sqrt(1.0 - mu0 * mu0), 0.0, -mu0}, {E0}};
    std::vector<SlabRun> runs;
    for (int r = 0; r < kRuns; ++r)
        runs.push_back(run_slab(s, sun, kPhotonsPerRun, 300 + static_cast<std::uint64_t>(r)));

    const double kappa = s.kappa, H = s.H, h = s.h, sigma_a = (1.0 - albedo) * kappa;
    // Q(z) = a kappa E0 exp(-beta (H - z)), beta = kappa / mu0; with S = ∫_0^H s exp(-beta s) ds:
    // ∫ (H - z) Q dz = a kappa E0 S and ∫ z Q dz = a kappa E0 (H (1 - exp(-beta H)) / beta - S).
    const double beta = kappa / mu0, eH = std::exp(-beta * H);
    const double S = 1.0 / (beta * beta) - eH * (H / beta + 1.0 / (beta * beta));
    const double zQ = albedo * kappa * E0 * (H * (1.0 - eH) / beta - S),
                 HzQ = albedo * kappa * E0 * S;
    // dF_z/dz = Q - sigma_a phi, integrated against z and against H - z:
    //   ∫ F_z dz = H R - ∫ z Q dz + sigma_a ∫ z phi dz = -H T + ∫ (H - z) Q dz - sigma_a ∫ (H - z) phi dz,
    // ∫ z phi dz from the layer means at their centres, plus (h²/12)(phi(H) - phi(0)) for the
    // slope inside the layers (second order; the remainder is far below the noise).
    const std::vector<MeanSe> balance = over_runs(runs, [&](const SlabRun& r) {
        double Fz = 0.0, zphi = 0.0, Hzphi = 0.0;
        for (int k = 0; k < kNz; ++k) {
            const double zc = (k + 0.5) * h, phi = r.layer[3][static_cast<size_t>(k)];
            Fz += h * r.layer[2][static_cast<size_t>(k)];
            zphi += h * zc * phi;
            Hzphi += h * (H - zc) * phi;
        }
        const double slope = h * h / 12.0 * (r.layer[3][kNz - 1] - r.layer[3][0]);
        return std::vector<double>{Fz - (H * r.R - zQ + sigma_a * (zphi + slope)),
                                   Fz - (-H * r.T + HzQ - sigma_a * (Hzphi - slope)), Fz};
    });
    for (int q = 0; q < 2; ++q) {
        const double t = balance[static_cast<size_t>(q)].mean / balance[static_cast<size_t>(q)].se;
        if (test::world_rank() == 0)
            std::printf("    ∫F_z dz = %.5f W/m; balance at the %s: %+.2e ± %.1e (t %+.2f)\n",
                        balance[2].mean, q == 0 ? "top" : "bottom",
                        balance[static_cast<size_t>(q)].mean, balance[static_cast<size_t>(q)].se,
                        t);
        EXPECT_LT(std::abs(t), 5.0) << (q == 0 ? "top" : "bottom");
    }
    // F_y = 0 by symmetry in every layer; F_x > 0 in the slab as a whole.
    const std::vector<MeanSe> fy = over_runs(runs, [](const SlabRun& r) {
        return std::vector<double>(r.layer[1].begin(), r.layer[1].end());
    });
    expect_t_values(fy, std::vector<double>(kNz, 0.0), "F_y = 0 under an oblique sun");
    const std::vector<MeanSe> fx = over_runs(runs, [](const SlabRun& r) {
        double sum = 0.0;
        for (const double v : r.layer[0]) sum += v / kNz;
        return std::vector<double>{sum};
    });
    if (test::world_rank() == 0)
        std::printf("    mean F_x %.5f ± %.5f W/m²\n", fx[0].mean, fx[0].se);
    EXPECT_GT(fx[0].mean, 10.0 * fx[0].se);
}

// Cell-averaged uncollided flux (W/m², 3 components) at the cell with low corner `det` (in
// cells) from a cell of power P (W) with low corner `src` in a pure absorber kappa:
//   F = (1/h³) ∫_det dx ∫_src dy (P/h³) exp(-kappa |u|) u / (4π |u|³),  u = x - y,
// with u's density per axis the triangle (h - |u_a - d_a|)/h² (emission_test.cpp's quadrature).
std::array<double, 3> point_source_flux(const Int3& src, const Int3& det, double h, double kappa,
                                        double P) {
    const double x[6] = {-0.9324695142031521, -0.6612093864662645, -0.2386191860831969,
                         0.2386191860831969,  0.6612093864662645,  0.9324695142031521};
    const double w[6] = {0.1713244923791704, 0.3607615730481386, 0.4679139345726910,
                         0.4679139345726910, 0.3607615730481386, 0.1713244923791704};
    std::array<double, 3> sum{0, 0, 0};
    double d[3];
    for (int a = 0; a < 3; ++a)
        d[a] = (det[static_cast<size_t>(a)] - src[static_cast<size_t>(a)]) * h;
    for (int side = 0; side < 8; ++side)
        for (int i = 0; i < 6; ++i)
            for (int j = 0; j < 6; ++j)
                for (int k = 0; k < 6; ++k) {
                    const int idx[3] = {i, j, k};
                    double u[3], wt = 1.0;
                    for (int a = 0; a < 3; ++a) {
                        const double t = 0.5 * h * (1.0 + x[idx[a]]);  // |u - d| in [0, h]
                        u[a] = d[a] + ((side >> a) & 1 ? t : -t);
                        wt *= w[idx[a]] * 0.5 * h * (h - t) / (h * h);
                    }
                    const double r = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
                    for (int a = 0; a < 3; ++a)
                        sum[static_cast<size_t>(a)] +=
                            wt * std::exp(-kappa * r) * u[a] / (4.0 * kPi * r * r * r);
                }
    for (double& v : sum) v *= P;
    return sum;
}

TEST(Flux, PointSourceInAPureAbsorber) {
    // 15^3 cells of 0.5 m, kappa 0.6 /m, a = 0; one emitting cell at (7, 7, 7) of 40 W/m³ (P = 5 W).
    const double h = 0.5, kappa = 0.6, q = 40.0, P = q * h * h * h;
    const Int3 n{15, 15, 15};
    Decomposition d(MPI_COMM_WORLD, n);
    Medium m;
    m.grid.n = n;
    m.grid.h = h;
    m.rho = Field<double>(d.local(), 1, 1, 1.0);
    m.bands = {BandOptics{"gray", kappa, 0.0, 0.0}};
    const std::vector<VolumeSource> src{{Box{{7, 7, 7}, {8, 8, 8}}, {q}}};
    MonteCarloOptions o;
    o.photons = 800000;
    o.seed = 5;
    const ForwardResult r = trace_forward(d, m, {}, src, o);
    const std::vector<Int3> detectors = {{9, 7, 7}, {5, 7, 7},  {7, 10, 7},   {7, 7, 3},
                                         {9, 9, 7}, {10, 4, 7}, {10, 10, 10}, {5, 9, 11},
                                         {3, 3, 3}, {12, 8, 6}};
    double z2 = 0.0, zmax = 0.0;
    for (const Int3& c : detectors) {
        double v[4] = {0, 0, 0, 0};  // F, phi
        if (d.local().contains(c[0], c[1], c[2])) {
            for (int a = 0; a < 3; ++a) v[a] = r.flux[0](c[0], c[1], c[2], a);
            v[3] = r.fluence[0](c[0], c[1], c[2]);
        }
        MPI_Allreduce(MPI_IN_PLACE, v, 4, MPI_DOUBLE, MPI_SUM, d.comm());
        const std::array<double, 3> exact = point_source_flux({7, 7, 7}, c, h, kappa, P);
        const double se =
            std::sqrt(P * v[3] / (static_cast<double>(r.photons) * kappa * h * h * h));
        for (int a = 0; a < 3; ++a) {
            const double z = (v[a] - exact[static_cast<size_t>(a)]) / se;
            z2 += z * z;
            zmax = std::max(zmax, std::abs(z));
        }
        if (test::world_rank() == 0)
            std::printf(
                "    point source: cell (%d,%d,%d): F (%+.4e %+.4e %+.4e) exact (%+.4e %+.4e "
                "%+.4e) ± %.1e\n",
                c[0], c[1], c[2], v[0], v[1], v[2], exact[0], exact[1], exact[2], se);
    }
    // se bounds the standard error from above (tight along r̂, loose across), so the z-values
    // are at most unit normal: max below 4 over 30, RMS below 1.3.
    const double rms = std::sqrt(z2 / (3.0 * static_cast<double>(detectors.size())));
    if (test::world_rank() == 0) std::printf("    point source: z rms %.3f, max %.2f\n", rms, zmax);
    EXPECT_LT(rms, 1.3);
    EXPECT_LT(zmax, 4.0);
}

}  // namespace
}  // namespace nimbus::mc
