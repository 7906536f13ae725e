// (a) Manufactured solution with variable kappa_tr, sigma_a and G on the unit cube, Marshak
// boundaries on all six faces: second-order convergence of the finite-volume scheme.
//
//   s(t) = sin²(πt),  S = s(x) s(y) s(z)   (S and ∇S vanish on the boundary)
//   kappa_tr = k0 (1 + S/2),  D = 1/(3 kappa_tr),  sigma_a = 0.3 (1 + x + y z)
//   G = gamma S (1, -2, 1/2)
//   U = X(x) X(y) X(z),  X(t) = 1 + t (1 - t)/(2 D0),  D0 = 1/(3 k0)
// On the boundary D = D0 and G = 0, and X(0) - 2 D0 X'(0) = 0 = X(1) + 2 D0 X'(1): U satisfies
// the Marshak condition U - 2D n·∇U + 2 n·G = 0 exactly. The source is
//   Q0 = -(∇D·∇U + D ΔU) + sigma_a U + ∇·G.
// The coefficients are flat at the boundary because the scheme (Max 2004 §2) takes the face
// value there from the full cell; see README.md.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/verification/diffusion/diffusion_test_util.h"
#include "solvers/diffusion/solve_diffusion.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double k0 = 2.0, gamma_g = 0.4;
const double D0 = 1.0 / (3.0 * k0);

double s(double t) { return std::sin(kPi * t) * std::sin(kPi * t); }
double ds(double t) { return kPi * std::sin(2.0 * kPi * t); }
double X(double t) { return 1.0 + t * (1.0 - t) / (2.0 * D0); }
double dX(double t) { return (1.0 - 2.0 * t) / (2.0 * D0); }
double d2X(double) { return -1.0 / D0; }

double kappa_tr(double x, double y, double z) { return k0 * (1.0 + 0.5 * s(x) * s(y) * s(z)); }
double sigma_a(double x, double y, double z) { return 0.3 * (1.0 + x + y * z); }
double U_exact(double x, double y, double z) { return X(x) * X(y) * X(z); }
Vec3 G(double x, double y, double z) {
    const double S = s(x) * s(y) * s(z);
    return Vec3{1.0, -2.0, 0.5} * (gamma_g * S);
}
double Q0(double x, double y, double z) {
    const double kt = kappa_tr(x, y, z), D = 1.0 / (3.0 * kt);
    const Vec3 grad_kt = Vec3{ds(x) * s(y) * s(z), s(x) * ds(y) * s(z), s(x) * s(y) * ds(z)} * (0.5 * k0);
    const Vec3 grad_D = grad_kt * (-1.0 / (3.0 * kt * kt));
    const Vec3 grad_U{dX(x) * X(y) * X(z), X(x) * dX(y) * X(z), X(x) * X(y) * dX(z)};
    const double lap_U = d2X(x) * X(y) * X(z) + X(x) * d2X(y) * X(z) + X(x) * X(y) * d2X(z);
    const double div_G = gamma_g * (1.0 * ds(x) * s(y) * s(z) - 2.0 * s(x) * ds(y) * s(z) +
                                    0.5 * s(x) * s(y) * ds(z));
    return -(dot(grad_D, grad_U) + D * lap_U) + sigma_a(x, y, z) * U_exact(x, y, z) + div_G;
}

double manufactured_error(int n) {
    const double h = 1.0 / n;
    Decomposition d(MPI_COMM_WORLD, {n, n, n});
    auto p = test::make_problem(d, h, kappa_tr, sigma_a, Q0, G);
    DiffusionOptions opt;
    opt.tolerance = 1e-12;
    Report report;
    const auto res = diffusion::solve_diffusion(d, p, opt, report);
    EXPECT_LE(res.stats[0].true_residual, opt.tolerance);
    double err = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double e = res.U[0](i, j, k) - U_exact((i + 0.5) * h, (j + 0.5) * h, (k + 0.5) * h);
        err = std::max(err, std::abs(e));
    });
    return test::global_max(err, MPI_COMM_WORLD);
}

TEST(DiffusionManufactured, SecondOrderWithVariableKappa) {
    const double e8 = manufactured_error(8), e16 = manufactured_error(16), e32 = manufactured_error(32);
    const double o1 = std::log2(e8 / e16), o2 = std::log2(e16 / e32);
    if (test::world_rank() == 0)
        std::printf("manufactured: max error n=8 %.3e, n=16 %.3e, n=32 %.3e; orders %.2f %.2f\n", e8,
                    e16, e32, o1, o2);
    EXPECT_GE(o1, 1.8);
    EXPECT_GE(o2, 1.8);
}

}  // namespace
}  // namespace nimbus
