// Verification of the diffusion model against closed-form P1 solutions:
//  (b) infinite-medium point source, U = S exp(-r/L) / (4π D r);
//  (c) plane-parallel slab under a collimated sun with Marshak boundaries at both faces
//      (periodic x/y), against the closed-form solution of the 1-D P1 equation.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/verification/diffusion/diffusion_test_util.h"
#include "solvers/diffusion/diffusion.h"
#include "solvers/diffusion/solve_diffusion.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr double kPi = std::numbers::pi;

// (b) A point source of strength S (∫ Q0 dV = S, in the centre cell) in a uniform medium with
// diffusion length L; the Marshak boundary is 5L away (e^-5 down). Compared at 1 <= r/L <= 2
// for h = L/4 and L/8: the 7-point scheme is second order (measured 4.4% -> 0.9%).
double point_source_error(int refine) {
    const double L = 1.0, h = L / (4 * refine), S = 1.0;
    const int n = 40 * refine + 1, c = n / 2;
    const double kappa_tr = 1.0 / h, D = 1.0 / (3.0 * kappa_tr), sigma_a = D / (L * L);
    Decomposition d(MPI_COMM_WORLD, {n, n, n});
    auto p = test::make_problem(
        d, h, [&](double, double, double) { return kappa_tr; },
        [&](double, double, double) { return sigma_a; },
        [&](double x, double y, double z) {
            const double x0 = (c + 0.5) * h, tol = 0.1 * h;
            const bool centre = std::abs(x - x0) < tol && std::abs(y - x0) < tol && std::abs(z - x0) < tol;
            return centre ? S / (h * h * h) : 0.0;
        },
        [](double, double, double) { return Vec3{}; });
    DiffusionOptions opt;
    opt.tolerance = 1e-10;
    Report report;
    const auto res = diffusion::solve_diffusion(d, p, opt, report);
    EXPECT_LE(res.stats[0].true_residual, opt.tolerance);
    double max_err = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double r = h * std::sqrt(double((i - c) * (i - c) + (j - c) * (j - c) + (k - c) * (k - c)));
        if (r < L || r > 2.0 * L) return;
        const double exact = S * std::exp(-r / L) / (4.0 * kPi * D * r);
        max_err = std::max(max_err, std::abs(res.U[0](i, j, k) / exact - 1.0));
    });
    return test::global_max(max_err, MPI_COMM_WORLD);
}

TEST(DiffusionAnalytic, InfiniteMediumPointSource) {
    const double e1 = point_source_error(1), e2 = point_source_error(2);
    const double order = std::log2(e1 / e2);
    if (test::world_rank() == 0)
        std::printf("point source: max relative error at L..2L: h=L/4 %.4f, h=L/8 %.4f, order %.2f\n", e1, e2, order);
    EXPECT_LT(e2, 0.01);
    EXPECT_GT(order, 1.8);
}

// (c) The 1-D P1 problem for a uniform slab 0 <= z <= H under a sun of irradiance E0 along
// w (mu0 = -w_z > 0), T = exp(-beta (H - z)), beta = kappa/mu0:
//   D U'' - sigma_a U = -Q0 + G',  Q0 = q e^{beta (z-H)},  q = kappa a E0/(4π),
//   G = Q1z/kappa_tr = -g mu0 Q0/kappa_tr  =>  G' = -g kappa Q0/kappa_tr,
// so D U'' - sigma_a U = -(1 + g kappa/kappa_tr) Q0. With k = sqrt(sigma_a/D):
//   U = A e^{beta (z-H)} + c1 e^{k (z-H)} + c2 e^{-k z},  A = -(1 + g kappa/kappa_tr) q / (D beta² - sigma_a),
// and Marshak at z = 0 (n = +z): U - 2D U' + 2G = 0, at z = H (n = -z): U + 2D U' - 2G = 0.
struct SlabP1 {
    double H, kappa, a, g, mu0, E0;
    double D, sigma_a, kappa_tr, k, beta, q, A, c1 = 0, c2 = 0;

    SlabP1(double H_, double kappa_, double a_, double g_, double mu0_, double E0_)
        : H(H_), kappa(kappa_), a(a_), g(g_), mu0(mu0_), E0(E0_) {
        kappa_tr = kappa * (1 - a * g);
        D = 1.0 / (3.0 * kappa_tr);
        sigma_a = kappa * (1 - a);
        k = std::sqrt(sigma_a / D);
        beta = kappa / mu0;
        q = kappa * a * E0 / (4 * kPi);
        A = -(1 + g * kappa / kappa_tr) * q / (D * beta * beta - sigma_a);
        auto G = [&](double z) { return -g * mu0 * q * std::exp(beta * (z - H)) / kappa_tr; };
        const double e = std::exp(-k * H);
        // [e(1-2Dk)  (1+2Dk)] [c1]   [-(A e^{-beta H}(1-2D beta) + 2G(0))]
        // [(1+2Dk)  e(1-2Dk)] [c2] = [-(A (1+2D beta) - 2G(H))           ]
        const double a11 = e * (1 - 2 * D * k), a12 = 1 + 2 * D * k;
        const double a21 = 1 + 2 * D * k, a22 = e * (1 - 2 * D * k);
        const double r1 = -(A * std::exp(-beta * H) * (1 - 2 * D * beta) + 2 * G(0));
        const double r2 = -(A * (1 + 2 * D * beta) - 2 * G(H));
        const double det = a11 * a22 - a12 * a21;
        c1 = (r1 * a22 - a12 * r2) / det;
        c2 = (a11 * r2 - a21 * r1) / det;
    }
    double U(double z) const {
        return A * std::exp(beta * (z - H)) + c1 * std::exp(k * (z - H)) + c2 * std::exp(-k * z);
    }
    // ∫_0^H U dz (k > 0).
    double integral() const {
        return A * -std::expm1(-beta * H) / beta + (c1 + c2) * -std::expm1(-k * H) / k;
    }
};

// The model on a uniform slab 0 <= z <= H of nz cells (5 x 6 columns, periodic x/y, Marshak at
// both faces) under a sun of irradiance E0 along w, without the transport-length cap (the
// closed form is the unregularized equation).
DiffuseSolution solve_slab(const Decomposition& d, double H, const BandOptics& band, const Vec3& w, double E0,
                           bool delta_scaling) {
    const double h = H / d.global().size(2);
    auto rho = [](int, int, int) { return 1.0; };
    Medium m = test::make_medium(d, h, band, rho);
    LightTransport light = test::column_light(d, h, w, E0, rho);
    Scene scene;
    Report report;
    SolveContext ctx{scene, d, m, light, report};
    DiffusionOptions opt;
    opt.tolerance = 1e-11;
    opt.delta_scaling = delta_scaling;
    opt.max_transport_length = 1e9;
    DiffuseSolution sol;
    make_diffusion_model(opt)->solve(ctx, sol);
    return sol;
}

// Max error of the model's fluence against the exact fluence, relative to the max of the exact
// P1 part 4π U (the forward peak, which the model adds in closed form, would only dilute the
// error: with it in the denominator the delta-Eddington error looked 400x smaller). Plain P1:
// 4π U. Delta-Eddington (solvers/diffusion/delta_scaling.h): the same closed form with the
// scaled optics kappa' = kappa (1 - a f), a' = a (1 - f)/(1 - a f), g' = g/(1 + g), f = g², plus
// the forward-peak light E0 (T' - T), T' = exp(-kappa' (H - z)/mu0), over the cell (the model's
// fluence is a cell mean there: LightTransport::forward_peak_mean).
double slab_error(int nz, double g, bool delta_scaling) {
    const double H = 8.0, h = H / nz, E0 = 2.0;
    const BandOptics band{"gray", 1.0, 0.9, g};
    const Vec3 w = normalized(Vec3{0.3, 0.2, -1.0});
    // 5 x 6 columns: periods that are not powers of two (hypre's manual warns that some of its
    // solvers need powers of two on periodic axes; PFMG-PCG does not).
    Decomposition d(MPI_COMM_WORLD, {5, 6, nz}, {0, 0, 0}, {true, true, false});
    const DiffuseSolution sol = solve_slab(d, H, band, w, E0, delta_scaling);
    const double kappa = 1.0, a = band.albedo, mu0 = -w.z;
    const double f = delta_scaling ? g * g : 0.0;
    const double kappa_s = kappa * (1 - a * f), a_s = a * (1 - f) / (1 - a * f);
    const double g_s = delta_scaling ? g / (1 + g) : g;
    const SlabP1 exact(H, kappa_s, a_s, g_s, mu0, E0);
    // The mean of e^{-k (H - z) / mu0} over the cell centred at z.
    auto cell_mean = [&](double k, double z) {
        const double x = k * h / mu0;
        return std::exp(-k * (H - z - 0.5 * h) / mu0) * -std::expm1(-x) / x;
    };
    auto fluence = [&](double z) {
        return 4 * kPi * exact.U(z) + E0 * (cell_mean(kappa_s, z) - cell_mean(kappa, z));
    };
    double err = 0.0, umax = 0.0;
    for (int k = 0; k < nz; ++k) umax = std::max(umax, 4 * kPi * std::abs(exact.U((k + 0.5) * h)));
    for_each_cell(d.local(), [&](int i, int j, int k) {
        err = std::max(err, std::abs(sol.fluence[0](i, j, k) - fluence((k + 0.5) * h)));
    });
    return test::global_max(err, MPI_COMM_WORLD) / umax;
}

TEST(DiffusionAnalytic, SlabUnderSunMatchesClosedFormP1) {
    for (bool delta : {false, true}) {
        for (double g : {0.0, 0.85}) {
            const double e1 = slab_error(32, g, delta), e2 = slab_error(64, g, delta),
                         e3 = slab_error(128, g, delta);
            const double order = std::log2(e2 / e3);
            if (test::world_rank() == 0)
                std::printf("slab %s g=%.2f: relative max error %.3e %.3e %.3e, order %.2f\n",
                            delta ? "delta-Eddington" : "plain P1", g, e1, e2, e3, order);
            // Measured at 128 cells: 6.9e-4 (g = 0), 6.1e-4 (plain P1, g = 0.85), 4.7e-6
            // (delta-Eddington, g = 0.85: the scaled problem is nearly isotropic and smooth).
            EXPECT_LT(e3, delta && g > 0.0 ? 1e-5 : 1e-3);
            EXPECT_GT(order, 1.8);
        }
    }
}

// Optically thick cells: a slab of 4 cells, each kappa h thick, at albedo 0.999. The first
// scatter lies in a sheet under the top face; placed at the top cell's centre it sat half a cell
// under the face, behind the half cell's diffusion resistance, and the slab's total of U came out
// 1.27x, 2.02x and 5.79x the closed form's at kappa h = 2, 5 and 20 (overhead sun; the same
// scheme in jobs/diffusion_thick_cells.py). With the sheet's direct escape (sources.cpp,
// sheet_escape) the part of the sheet's light that the P1 Green's function sends through the
// face leaves: measured 1.077, 1.055, 0.980 overhead (as the script's "sheet" column) and 1.071,
// 1.040, 0.974 under the oblique sun.
TEST(DiffusionAnalytic, ThickCellsKeepTheSlabsTotal) {
    // (The delta-Eddington case is ThickCellsKeepTheSlabsTotalWithAForwardPeak below.)
    const BandOptics band{"gray", 1.0, 0.999, 0.0};
    for (const Vec3& w : {Vec3{0.0, 0.0, -1.0}, normalized(Vec3{0.5, 0.3, -0.8})}) {
        for (double kappa_h : {2.0, 5.0, 20.0}) {
            const int nz = 4;
            const double H = nz * kappa_h / band.sigma_t, h = H / nz, E0 = 2.0;
            Decomposition d(MPI_COMM_WORLD, {5, 6, nz}, {0, 0, 0}, {true, true, false});
            const DiffuseSolution sol = solve_slab(d, H, band, w, E0, false);
            double total = 0.0;  // ∫ 4π U dz over one column
            for_each_cell(d.local(), [&](int i, int j, int k) {
                if (i == 0 && j == 0) total += sol.fluence[0](i, j, k) * h;
            });
            total = test::global_sum(total, MPI_COMM_WORLD);
            const SlabP1 exact(H, band.sigma_t, band.albedo, band.g, -w.z, E0);
            const double ratio = total / (4 * kPi * exact.integral());
            if (test::world_rank() == 0)
                std::printf("thick slab, w_z = %.2f, kappa h = %g: total U / closed form %.3f\n", w.z, kappa_h, ratio);
            EXPECT_NEAR(ratio, 1.0, 0.1) << "w_z = " << w.z << ", kappa h = " << kappa_h;
        }
    }
}

// The same slab of 4 thick cells with a forward peak and absorption (albedo 0.9, g = 0.85,
// delta-Eddington): the total fluence, 4π U' plus the peak E0 (T' - T), against the closed form
// (the P1 slab with the scaled optics plus the peak's exact integral). The peak is much of a
// thick lit cell's fluence, and at kappa h = 20 its cell mean is 3.1x the difference at the
// centre, which the model used until the fortieth session: 1.019, 1.027, 0.778 at kappa h = 2,
// 5, 20 overhead and 1.024, 1.020, 0.727 oblique then; with the cells' means 1.003, 0.995, 0.937
// and 1.002, 0.990, 0.930 (the rest at 20 is the scheme's: its forward flux G, averaged over the
// lit cell, reaches the face below, where the true G is e^{-10} of it; jobs/diffusion_thick_cells.py).
TEST(DiffusionAnalytic, ThickCellsKeepTheSlabsTotalWithAForwardPeak) {
    const BandOptics band{"gray", 1.0, 0.9, 0.85};
    const double f = band.g * band.g, kappa = band.sigma_t, a = band.albedo;
    const double kappa_s = kappa * (1 - a * f), a_s = a * (1 - f) / (1 - a * f), g_s = band.g / (1 + band.g);
    for (const Vec3& w : {Vec3{0.0, 0.0, -1.0}, normalized(Vec3{0.5, 0.3, -0.8})}) {
        for (double kappa_h : {2.0, 5.0, 20.0}) {
            const int nz = 4;
            const double H = nz * kappa_h / kappa, h = H / nz, E0 = 2.0, mu0 = -w.z;
            Decomposition d(MPI_COMM_WORLD, {5, 6, nz}, {0, 0, 0}, {true, true, false});
            const DiffuseSolution sol = solve_slab(d, H, band, w, E0, true);
            double total = 0.0;  // ∫ fluence dz over one column
            for_each_cell(d.local(), [&](int i, int j, int k) {
                if (i == 0 && j == 0) total += sol.fluence[0](i, j, k) * h;
            });
            total = test::global_sum(total, MPI_COMM_WORLD);
            const SlabP1 exact(H, kappa_s, a_s, g_s, mu0, E0);
            // ∫_0^H (e^{-kappa' s / mu0} - e^{-kappa s / mu0}) ds
            const double peak = mu0 * (-std::expm1(-kappa_s * H / mu0) / kappa_s - -std::expm1(-kappa * H / mu0) / kappa);
            const double ratio = total / (4 * kPi * exact.integral() + E0 * peak);
            if (test::world_rank() == 0)
                std::printf("thick slab, albedo 0.9, g 0.85, w_z = %.2f, kappa h = %g: total fluence / closed form %.3f\n",
                            w.z, kappa_h, ratio);
            EXPECT_NEAR(ratio, 1.0, 0.1) << "w_z = " << w.z << ", kappa h = " << kappa_h;
        }
    }
}

}  // namespace
}  // namespace nimbus
