// Flux-limited diffusion (solvers/diffusion/flux_limiter.h): the Levermore-Pomraning function,
// the flux bound |F| <= 4πU that P1 violates in thin media, and agreement with P1 where the
// medium is thick (R -> 0, lambda -> 1/3).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/verification/diffusion/diffusion_test_util.h"
#include "solvers/diffusion/diffusion.h"
#include "solvers/diffusion/flux_limiter.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

using diffusion::levermore_pomraning;

TEST(FluxLimiter, LevermorePomraningLimits) {
    EXPECT_DOUBLE_EQ(levermore_pomraning(0.0), 1.0 / 3.0);
    // The three branches (series, closed form, large R) meet continuously.
    for (double R : {0.1, 20.0})
        EXPECT_NEAR(levermore_pomraning(R * (1 - 1e-12)), levermore_pomraning(R * (1 + 1e-12)), 1e-12);
    // Free streaming: lambda R -> 1, and never above (|F| <= 4πU).
    EXPECT_NEAR(levermore_pomraning(1e3) * 1e3, 1.0, 1.1e-3);
    double previous = 1.0;
    for (double R = 1e-4; R < 1e3; R *= 1.1) {
        const double l = levermore_pomraning(R);
        EXPECT_LT(l * R, 1.0) << R;
        EXPECT_LT(l, previous) << R;  // monotonically decreasing
        previous = l;
    }
    // A value: lambda(1) = coth(1) - 1 = 0.3130352855.
    EXPECT_NEAR(levermore_pomraning(1.0), 0.3130352854993313, 1e-12);
}

constexpr int kN = 24;

double cube(int i, int j, int k) {
    auto in = [](int a) { return a >= 4 && a < kN - 4; };
    return in(i) && in(j) && in(k) ? 1.0 : 0.0;
}

// Largest |F| / (4πU) over the full cells (delta scaling off: the output is the P1 field alone).
double max_flux_ratio(const DiffuseSolution& sol, const Decomposition& d) {
    double worst = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double phi = sol.fluence[0](i, j, k);
        if (cube(i, j, k) == 0.0 || phi <= 0.0) return;
        const double* F = &sol.flux[0](i, j, k);
        worst = std::max(worst, std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]) / phi);
    });
    return test::global_max(worst, d.comm());
}

DiffuseSolution run(const Decomposition& d, const BandOptics& band, double h, const std::string& limiter,
                    Report& report, double limiter_tolerance = 1e-3) {
    DiffusionOptions opt;
    opt.delta_scaling = false;
    opt.flux_limiter = limiter;
    if (limiter != "none") {  // read only with the limiter (DiffusionOptions::validate)
        opt.limiter_tolerance = limiter_tolerance;
        opt.limiter_iterations = 100;
    }
    auto model = make_diffusion_model(opt);
    return test::run_model(*model, d, h, band, cube, normalized(Vec3{0.3, 0.2, -1.0}), report);
}

TEST(FluxLimiter, BoundsTheFluxWhereP1ExceedsIt) {
    // A cube of optical thickness 16 with g = 0.85 (kappa_tr h = 0.235, above the transport cap
    // of this region): the forward-peaked first-scatter flux G = Q1/kappa_tr makes the P1 flux
    // exceed what any radiance can carry near the lit faces; the limiter keeps |F| <= 4πU.
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    const BandOptics thin{"gray", 1.0, 0.9, 0.85};
    Report r1, r2;
    const double p1 = max_flux_ratio(run(d, thin, 1.0, "none", r1), d);
    const double fld = max_flux_ratio(run(d, thin, 1.0, "levermore-pomraning", r2), d);
    if (test::world_rank() == 0)
        std::printf("cube: max |F|/(4πU) P1 %.3f, flux-limited %.3f\n", p1, fld);
    EXPECT_GT(p1, 10.0);
    EXPECT_LE(fld, 1.0);
}

TEST(FluxLimiter, StopsNearTheFixedPointWhereTheCapSetsD) {
    // A thin cube (optical thickness 2.2, kappa_tr = 0.1 /m below the cap's floor 1/8 /m): P1's
    // D is the cap's in every cell, and only a lambda below kappa_tr / (3 floor) = 0.27 changes
    // U. The old damped step lambda <- (lambda + lambda(R)) / 2 stayed above it: U did not move,
    // the change test passed after one iteration, 2% from the fixed point (and 11% on the smoke
    // scene). The fixed point here was confirmed by plain undamped Picard (15 iterations to
    // 1e-6, the same field). The answer at tolerance 1e-2 must be within 1e-2 of the one at 1e-6
    // (measured 7.2e-4; 3.5e-3 when one small change stopped it), which must differ from P1
    // (measured 2.0e-2).
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    const BandOptics thin{"gray", 0.137, 0.9, 0.3};
    Report r0, r1, r2;
    const auto p1 = run(d, thin, 1.0, "none", r0);
    const auto loose = run(d, thin, 1.0, "levermore-pomraning", r1, 1e-2);
    const auto tight = run(d, thin, 1.0, "levermore-pomraning", r2, 1e-6);
    const int picard = r1.values()["diffusion"]["flux_limiter"][0]["picard_iterations"].get<int>();
    double d_loose = 0.0, d_p1 = 0.0, peak = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        d_loose = std::max(d_loose, std::abs(loose.fluence[0](i, j, k) - tight.fluence[0](i, j, k)));
        d_p1 = std::max(d_p1, std::abs(p1.fluence[0](i, j, k) - tight.fluence[0](i, j, k)));
        peak = std::max(peak, tight.fluence[0](i, j, k));
    });
    d_loose = test::global_max(d_loose, d.comm()) / test::global_max(peak, d.comm());
    d_p1 = test::global_max(d_p1, d.comm()) / test::global_max(peak, d.comm());
    if (test::world_rank() == 0)
        std::printf("thin cube: %d Picard iterations at 1e-2 (%d at 1e-6); max |loose - tight| / max %.2e, "
                    "|P1 - tight| / max %.2e\n",
                    picard, r2.values()["diffusion"]["flux_limiter"][0]["picard_iterations"].get<int>(), d_loose,
                    d_p1);
    EXPECT_GT(picard, 1);
    // The report has one systems entry per linear solve: the P1 start and one per iteration.
    const auto& systems = r1.values()["diffusion"]["systems"];
    ASSERT_EQ(systems.size(), static_cast<size_t>(picard) + 1);
    for (size_t e = 0; e < systems.size(); ++e) {
        EXPECT_EQ(systems[e]["limiter_iteration"].get<int>(), static_cast<int>(e));
        EXPECT_EQ(systems[e]["bands"], nlohmann::json::array({"gray"}));
    }
    EXPECT_GT(d_p1, 1e-2);
    EXPECT_LT(d_loose, 1e-2);
}

TEST(FluxLimiter, ACloudInOneRanksSlabMatchesOneRank) {
    // The cloud in the lowest 6 of 24 layers: on 2 and 3 ranks the ranks above hold none of the
    // solve region (its margin is 2). Each iteration's G lives on that region, and the copy the
    // limiter solves with lost it (rhs_within), so its halo exchange ran over the whole domain:
    // the ranks with a part waited for those without one, for ever (a QA finding).
    const auto low = [](int i, int j, int k) { return i >= 4 && i < kN - 4 && j >= 4 && j < kN - 4 && k < 6 ? 1.0 : 0.0; };
    const BandOptics band{"gray", 1.0, 0.9, 0.85};
    DiffusionOptions opt;
    opt.flux_limiter = "levermore-pomraning";
    opt.limiter_tolerance = 1e-4;
    Decomposition world(MPI_COMM_WORLD, {kN, kN, kN}), self(MPI_COMM_SELF, {kN, kN, kN});
    Report r1, r2;
    auto a = make_diffusion_model(opt), b = make_diffusion_model(opt);
    const DiffuseSolution w = test::run_model(*a, world, 1.0, band, low, normalized(Vec3{0.3, 0.2, -1.0}), r1);
    const DiffuseSolution one = test::run_model(*b, self, 1.0, band, low, normalized(Vec3{0.3, 0.2, -1.0}), r2);
    double diff = 0.0, peak = 0.0;
    for_each_cell(world.local(), [&](int i, int j, int k) {
        diff = std::max(diff, std::abs(w.fluence[0](i, j, k) - one.fluence[0](i, j, k)));
        peak = std::max(peak, one.fluence[0](i, j, k));
    });
    diff = test::global_max(diff, world.comm());
    peak = test::global_max(peak, world.comm());
    if (test::world_rank() == 0) std::printf("cloud in the lowest slab: max |all ranks - 1 rank| / max %.1e\n", diff / peak);
    EXPECT_GT(peak, 0.0);
    EXPECT_LT(diff, 1e-6 * peak);
    EXPECT_GT(r1.values()["diffusion"]["flux_limiter"][0]["picard_iterations"].get<int>(), 1);
}

TEST(FluxLimiter, AgreesWithP1InsideAThickMedium) {
    // Optical thickness 64 across the cube (kappa_tr h = 4 with g = 0): R << 1 inside.
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    const BandOptics thick{"gray", 4.0, 0.99, 0.0};
    Report r1, r2;
    const auto p1 = run(d, thick, 1.0, "none", r1);
    const auto fld = run(d, thick, 1.0, "levermore-pomraning", r2);
    double diff = 0.0, peak = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        auto deep = [](int a) { return a >= 8 && a < kN - 8; };
        if (!(deep(i) && deep(j) && deep(k))) return;
        diff = std::max(diff, std::abs(fld.fluence[0](i, j, k) - p1.fluence[0](i, j, k)));
        peak = std::max(peak, p1.fluence[0](i, j, k));
    });
    diff = test::global_max(diff, d.comm());
    peak = test::global_max(peak, d.comm());
    if (test::world_rank() == 0) std::printf("thick cube interior: max |FLD - P1| / max = %.2e\n", diff / peak);
    EXPECT_LT(diff / peak, 5e-3);  // measured 1.7e-3 (1.3e-3 with the damped iteration)
}

}  // namespace
}  // namespace nimbus
