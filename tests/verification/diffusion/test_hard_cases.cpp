// Hard cases for the diffusion model: each must converge (true residual <= tol) within a
// bounded number of PFMG-PCG iterations and give finite, non-negative fluence everywhere.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/verification/diffusion/diffusion_test_util.h"
#include "solvers/diffusion/diffusion.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr int kN = 24;
// Measured: at most 7 PFMG-PCG iterations (1 and 2 ranks); twice that is the bound.
constexpr int kMaxIterations = 14;

struct Case {
    const char* name;
    BandOptics band;
    double h;
    std::function<double(int, int, int)> rho;
    Vec3 sun;
};

double sphere(int i, int j, int k) {
    const double c = 0.5 * kN, r = 0.35 * kN;
    const double x = i + 0.5 - c, y = j + 0.5 - c, z = k + 0.5 - c;
    return x * x + y * y + z * z <= r * r ? 1.0 : 0.0;
}

void run_case(const Case& c) {
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    DiffusionOptions opt;
    opt.max_iterations = kMaxIterations;
    auto model = make_diffusion_model(opt);
    Report report;
    const auto sol = test::run_model(*model, d, c.h, c.band, c.rho, c.sun, report);
    const auto& sys = report.values()["diffusion"]["systems"][0];
    const int its = sys["iterations"].get<int>();
    const double res = sys["true_residual"].get<double>();
    const auto neg_boundary = sys["negative_boundary_cells"].get<std::int64_t>();
    const auto neg_interior = sys["negative_interior_cells"].get<std::int64_t>();
    double fmin = 1e300, fmax = -1e300;
    bool finite = true;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double f = sol.fluence[0](i, j, k);
        finite = finite && std::isfinite(f);
        fmin = std::min(fmin, f);
        fmax = std::max(fmax, f);
    });
    fmin = test::global_min(fmin, MPI_COMM_WORLD);
    fmax = test::global_max(fmax, MPI_COMM_WORLD);
    if (test::world_rank() == 0)
        std::printf("%-28s %3d iterations, true residual %.2e, fluence [%.3e, %.3e], negative P1 "
                    "cells clamped: %lld at the surface, %lld inside (min U / max U %.2e)\n",
                    c.name, its, res, fmin, fmax, static_cast<long long>(neg_boundary),
                    static_cast<long long>(neg_interior), sys["min_U"].get<double>() / sys["max_U"].get<double>());
    EXPECT_TRUE(finite) << c.name;
    EXPECT_LE(its, kMaxIterations) << c.name;
    EXPECT_LE(res, opt.tolerance) << c.name;
    // The written fluence: the clamp (clamp_negative, default) leaves no negative P1 value, and
    // the forward peak added to it is never negative.
    EXPECT_GE(fmin, 0.0) << c.name;
    // The P1 solution itself, before the clamp, against its own maximum (the written maximum
    // includes the forward peak): negative only in the boundary layer lit by the
    // forward-peaked source (cells with a Marshak face; measured: only the cloud touching the
    // boundary, 1 cell at -2.3% of max U; bound 5%);
    // inside, at most solver round-off, in every case (with delta-Eddington sources also for
    // kappa h = 1e-4 and g = 0.99).
    const double umax = sys["max_U"].get<double>();
    EXPECT_GT(umax, 0.0) << c.name;
    EXPECT_GE(sys["min_U"].get<double>(), -0.05 * umax) << c.name;
    EXPECT_GE(sys["min_U_interior"].get<double>(), -opt.tolerance * umax) << c.name;
    EXPECT_GT(fmax, 0.0) << c.name;
}

const Vec3 kOblique = normalized(Vec3{0.3, 0.2, -1.0});
const Vec3 kDown{0.0, 0.0, -1.0};

TEST(DiffusionHardCases, AlbedoOne) { run_case({"albedo 1", {"gray", 2.0, 1.0, 0.85}, 0.25, sphere, kOblique}); }

TEST(DiffusionHardCases, DensityJump1e6) {
    auto rho = [](int i, int j, int k) {
        const double s = sphere(i, j, k);
        return i < kN / 2 ? s : 1e-6 * s;
    };
    run_case({"density jump 1e6", {"gray", 4.0, 0.9, 0.85}, 0.25, rho, kOblique});
}

TEST(DiffusionHardCases, OpticallyThickCells) {
    run_case({"kappa h = 100", {"gray", 100.0, 0.9, 0.85}, 1.0, sphere, kDown});
}

TEST(DiffusionHardCases, OpticallyThinCells) {
    run_case({"kappa h = 1e-4", {"gray", 1e-4, 0.9, 0.85}, 1.0, sphere, kOblique});
}

TEST(DiffusionHardCases, SingleFullCell) {
    auto rho = [](int i, int j, int k) { return i == 11 && j == 12 && k == 13 ? 1.0 : 0.0; };
    run_case({"single full cell", {"gray", 2.0, 0.9, 0.85}, 0.25, rho, kOblique});
}

TEST(DiffusionHardCases, ForwardPeakedG099) {
    run_case({"g = 0.99", {"gray", 4.0, 0.99, 0.99}, 0.25, sphere, kOblique});
}

TEST(DiffusionHardCases, CloudTouchingDomainBoundary) {
    auto rho = [](int, int, int k) { return k < 15 ? 1.0 : 0.0; };
    run_case({"cloud touching the boundary", {"gray", 2.0, 0.9, 0.85}, 0.25, rho, kOblique});
}

}  // namespace
}  // namespace nimbus
