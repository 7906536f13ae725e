// (a) Manufactured solution with variable kappa_tr, sigma_a and G on the unit cube, Marshak
// boundaries on all six faces: second-order convergence of the finite-volume scheme.
//
//   s(t) = sin²(πt),  S = s(x) s(y) s(z)   (S and ∇S vanish on the boundary)
//   kappa_tr = k0 (1 + S/2),  D = 1/(3 kappa_tr),  sigma_a = 0.3 (1 + x + y z)
//   G = gamma S (1, -2, 1/2) + beta ∇U
//   U = X(x) X(y) X(z),  X(t) = 1 + t (1 - t)/(2 D1),  D1 = D0 - beta,  D0 = 1/(3 k0)
// On the boundary D = D0 and n·G = beta n·∇U, and X(0) - 2 D1 X'(0) = 0 = X(1) + 2 D1 X'(1):
// U satisfies the Marshak condition U - 2 D0 n·∇U + 2 n·G = U - 2 D1 n·∇U = 0 exactly. With
// beta = 0 the boundary G is zero; with beta != 0 the Marshak face's G term, (n·G) h²/(4D+h)
// in diffusion_kernel.h, carries a G that varies across the boundary cell. The source is
//   Q0 = -(∇D·∇U + D ΔU) + sigma_a U + ∇·G,  ∇·G = gamma ∇S·(1, -2, 1/2) + beta ΔU.
// D is flat at the boundary because the scheme (Max 2004 §2) takes the face value there from
// the full cell; see README.md.
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
double kappa_tr(double x, double y, double z) { return k0 * (1.0 + 0.5 * s(x) * s(y) * s(z)); }
double sigma_a(double x, double y, double z) { return 0.3 * (1.0 + x + y * z); }

struct Manufactured {
    double beta;  // G's share of ∇U: n·G on the boundary is beta n·∇U
    double D1() const { return D0 - beta; }
    double X(double t) const { return 1.0 + t * (1.0 - t) / (2.0 * D1()); }
    double dX(double t) const { return (1.0 - 2.0 * t) / (2.0 * D1()); }
    double d2X(double) const { return -1.0 / D1(); }
    double U(double x, double y, double z) const { return X(x) * X(y) * X(z); }
    Vec3 grad_U(double x, double y, double z) const {
        return {dX(x) * X(y) * X(z), X(x) * dX(y) * X(z), X(x) * X(y) * dX(z)};
    }
    double lap_U(double x, double y, double z) const {
        return d2X(x) * X(y) * X(z) + X(x) * d2X(y) * X(z) + X(x) * X(y) * d2X(z);
    }
    Vec3 G(double x, double y, double z) const {
        return Vec3{1.0, -2.0, 0.5} * (gamma_g * s(x) * s(y) * s(z)) + grad_U(x, y, z) * beta;
    }
    double Q0(double x, double y, double z) const {
        const double kt = kappa_tr(x, y, z), D = 1.0 / (3.0 * kt);
        const Vec3 grad_kt = Vec3{ds(x) * s(y) * s(z), s(x) * ds(y) * s(z), s(x) * s(y) * ds(z)} * (0.5 * k0);
        const Vec3 grad_D = grad_kt * (-1.0 / (3.0 * kt * kt));
        const double div_G = gamma_g * (1.0 * ds(x) * s(y) * s(z) - 2.0 * s(x) * ds(y) * s(z) +
                                        0.5 * s(x) * s(y) * ds(z)) +
                             beta * lap_U(x, y, z);
        return -(dot(grad_D, grad_U(x, y, z)) + D * lap_U(x, y, z)) + sigma_a(x, y, z) * U(x, y, z) + div_G;
    }
};

double manufactured_error(const Manufactured& m, int n) {
    const double h = 1.0 / n;
    Decomposition d(MPI_COMM_WORLD, {n, n, n});
    auto p = test::make_problem(
        d, h, kappa_tr, sigma_a, [&](double x, double y, double z) { return m.Q0(x, y, z); },
        [&](double x, double y, double z) { return m.G(x, y, z); });
    DiffusionOptions opt;
    opt.tolerance = 1e-12;
    Report report;
    const auto res = diffusion::solve_diffusion(d, p, opt, report);
    EXPECT_LE(res.stats[0].true_residual, opt.tolerance);
    double err = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double e = res.U[0](i, j, k) - m.U((i + 0.5) * h, (j + 0.5) * h, (k + 0.5) * h);
        err = std::max(err, std::abs(e));
    });
    return test::global_max(err, MPI_COMM_WORLD);
}

void expect_second_order(const Manufactured& m) {
    const double e8 = manufactured_error(m, 8), e16 = manufactured_error(m, 16), e32 = manufactured_error(m, 32);
    const double o1 = std::log2(e8 / e16), o2 = std::log2(e16 / e32);
    if (test::world_rank() == 0)
        std::printf("manufactured (beta %.3f): max error n=8 %.3e, n=16 %.3e, n=32 %.3e; orders %.2f %.2f\n",
                    m.beta, e8, e16, e32, o1, o2);
    EXPECT_GE(o1, 1.8);
    EXPECT_GE(o2, 1.8);
}

TEST(DiffusionManufactured, SecondOrderWithVariableKappa) { expect_second_order({0.0}); }

// n·G != 0 on every boundary face, varying across the boundary cells.
TEST(DiffusionManufactured, SecondOrderWithFluxSourceOnTheMarshakFaces) { expect_second_order({0.5 * D0}); }

}  // namespace
}  // namespace nimbus
