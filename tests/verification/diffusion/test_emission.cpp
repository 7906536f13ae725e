// Volume emission ([[sources]], src/scene/emission.h) in the diffusion model: an isotropic
// source q = power/4π (W/m³/sr) adds to Q0 of the P1 equation and nothing to Q1 (sources.h).
//  - infinite medium (periodic on every axis), uniform source: σ_a U = q exactly, so the
//    fluence is power/σ_a in every cell, which is also the transport answer;
//  - one emitting cell in a uniform absorbing, scattering medium: the point-source solution
//    U = S exp(-r/L)/(4π D r), S = power V/4π, at L <= r <= 2L (as test (b) in
//    test_analytic.cpp, here through the scene's [[sources]]), and equal to the same problem
//    assembled directly from Q0 (test::make_problem) to the solver tolerance;
//  - superposition with lights: three bands under a sun and a source of different colours are
//    solved in 2 right-hand sides (band_groups.h) and equal each band solved alone.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/verification/diffusion/diffusion_test_util.h"
#include "solvers/diffusion/diffusion.h"
#include "solvers/diffusion/solve_diffusion.h"
#include "src/scene/medium.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr double kPi = std::numbers::pi;

// A scene that holds only what the diffusion model reads of it: the grid (for the sources'
// cell boxes), the bands and the sources.
Scene emitting_scene(const Int3& n, double h, const std::vector<BandOptics>& bands, std::vector<SourceSpec> sources) {
    Scene s;
    s.grid.n = {n[0], n[1], n[2]};
    s.grid.cell_size = h;
    s.bands = bands;
    s.sources = std::move(sources);
    s.model.name = "diffusion";
    return s;
}

DiffuseSolution solve(const Scene& scene, const Decomposition& d, const Medium& m, const LightTransport& light,
                      double tol, Report& report, bool clamp_negative = true) {
    DiffusionOptions opt;
    opt.tolerance = tol;
    opt.clamp_negative = clamp_negative;
    auto model = make_diffusion_model(opt);
    DiffuseSolution sol;
    model->solve(SolveContext{scene, d, m, light, report}, sol);
    return sol;
}

TEST(DiffusionEmission, UniformSourceInAnInfiniteMediumGivesPowerOverSigmaA) {
    const Int3 n{8, 8, 8};
    const double h = 0.5, power = 3.0;
    const BandOptics band{"gray", 2.0, 0.9, 0.7};  // sigma_a = 0.2 /m
    Decomposition d(MPI_COMM_WORLD, n, {0, 0, 0}, {true, true, true});
    const Medium m = test::make_medium(d, h, band, [](int, int, int) { return 1.0; });
    const Scene scene = emitting_scene(n, h, {band}, {SourceSpec{{0, 0, 0}, {4, 4, 4}, {power}}});
    Report report;
    const DiffuseSolution sol = solve(scene, d, m, LightTransport{}, 1e-12, report);
    const double exact = power / (band.sigma_t * (1 - band.albedo));
    double err = 0.0, flux = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        err = std::max(err, std::abs(sol.fluence[0](i, j, k) / exact - 1.0));
        for (int c = 0; c < 3; ++c) flux = std::max(flux, std::abs(sol.flux[0](i, j, k, c)));
    });
    err = test::global_max(err, MPI_COMM_WORLD);
    flux = test::global_max(flux, MPI_COMM_WORLD);
    if (test::world_rank() == 0) std::printf("uniform source: max |fluence / (P/sigma_a) - 1| = %.2e\n", err);
    EXPECT_LT(err, 1e-9);
    EXPECT_LT(flux, 1e-9 * exact);
}

// No light term and no source (e.g. sun.enabled = false, no sky): nothing to solve, the diffuse
// field is zero (this used to index the first of zero right-hand sides and crash).
TEST(DiffusionEmission, NothingLitIsZeroWithoutASolve) {
    const Int3 n{6, 6, 8};
    const double h = 0.5;
    const BandOptics band{"gray", 2.0, 0.9, 0.7};
    Decomposition d(MPI_COMM_WORLD, n);
    const Medium m = test::make_medium(d, h, band, [](int, int, int) { return 1.0; });
    for (const char* limiter : {"none", "levermore-pomraning"}) {
        const Scene scene = emitting_scene(n, h, {band}, {});
        DiffusionOptions opt;
        opt.flux_limiter = limiter;
        Report report;
        DiffuseSolution sol;
        make_diffusion_model(opt)->solve(SolveContext{scene, d, m, LightTransport{}, report}, sol);
        ASSERT_EQ(sol.fluence.size(), 1u);
        double peak = 0.0;
        for_each_cell(d.local(), [&](int i, int j, int k) {
            peak = std::max(peak, std::abs(sol.fluence[0](i, j, k)));
            for (int c = 0; c < 3; ++c) peak = std::max(peak, std::abs(sol.flux[0](i, j, k, c)));
        });
        EXPECT_EQ(test::global_max(peak, MPI_COMM_WORLD), 0.0) << limiter;
        EXPECT_EQ(report.values()["diffusion"]["solves"].get<int>(), 0) << limiter;
    }
}

TEST(DiffusionEmission, OneEmittingCellIsThePointSourceSolution) {
    // h = L/4, the Marshak boundary 5L away (as point_source_error(1) in test_analytic.cpp):
    // kappa h = 1, g = 0, D = h/3, sigma_a = D/L², so 1 - a = 1/48.
    const int n = 41, c = n / 2;
    const double h = 0.25, L = 4 * h, power = 5.0;
    const double D = h / 3, sigma_a = D / (L * L);
    const BandOptics band{"gray", 1.0 / h, 1.0 - sigma_a * h, 0.0};
    Decomposition d(MPI_COMM_WORLD, {n, n, n});
    const Medium m = test::make_medium(d, h, band, [](int, int, int) { return 1.0; });
    const double lo = c * h + 0.1 * h, hi = (c + 1) * h - 0.1 * h;  // covers the centre of cell c only
    const Scene scene = emitting_scene({n, n, n}, h, {band}, {SourceSpec{{lo, lo, lo}, {hi, hi, hi}, {power}}});
    Report report;
    const double tol = 1e-10;
    const DiffuseSolution sol = solve(scene, d, m, LightTransport{}, tol, report);

    // The same system assembled from Q0 directly: one cell of Q0 = power/4π.
    auto p = test::make_problem(
        d, h, [&](double, double, double) { return band.sigma_t; }, [&](double, double, double) { return sigma_a; },
        [&](double x, double y, double z) {
            const double x0 = (c + 0.5) * h, eps = 0.1 * h;
            const bool centre = std::abs(x - x0) < eps && std::abs(y - x0) < eps && std::abs(z - x0) < eps;
            return centre ? power / (4 * kPi) : 0.0;
        },
        [](double, double, double) { return Vec3{}; });
    DiffusionOptions opt;
    opt.tolerance = tol;
    Report r2;
    const auto direct = diffusion::solve_diffusion(d, p, opt, r2);

    const double S = power * h * h * h / (4 * kPi);
    double err = 0.0, diff = 0.0, fmax = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        const double f = sol.fluence[0](i, j, k);
        fmax = std::max(fmax, f);
        diff = std::max(diff, std::abs(f - 4 * kPi * direct.U[0](i, j, k)));
        const double r = h * std::sqrt(double((i - c) * (i - c) + (j - c) * (j - c) + (k - c) * (k - c)));
        if (r < L || r > 2 * L) return;
        err = std::max(err, std::abs(f / (4 * kPi * S * std::exp(-r / L) / (4 * kPi * D * r)) - 1.0));
    });
    err = test::global_max(err, MPI_COMM_WORLD);
    diff = test::global_max(diff, MPI_COMM_WORLD);
    fmax = test::global_max(fmax, MPI_COMM_WORLD);
    if (test::world_rank() == 0)
        std::printf("one emitting cell: max relative error at L..2L %.4f; vs direct Q0 %.2e of the peak\n", err,
                    diff / fmax);
    EXPECT_LT(err, 0.05);  // the 7-point scheme's error at h = L/4 (4.4% in test_analytic.cpp)
    EXPECT_LT(diff, 1e-7 * fmax);
}

// Sun and source with different colours over 3 bands of equal optics: by colour, 2 right-hand
// sides (one per term); each band equals the band solved alone, and sun + source equals the
// sum of the two solved apart (P1 is linear; clamping negative fluence is not, so it is off).
TEST(DiffusionEmission, SourceAndSunShareSolvesAndAddUp) {
    const int n = 20;
    const double h = 0.25, tol = 1e-11;
    const BandOptics band{"gray", 3.0, 0.9, 0.85};
    const Vec3 sun = normalized(Vec3{0.3, 0.2, -1.0});
    static const ProceduralDensity cloud(MediumSpec{}, {n, n, n});
    auto rho = [](int i, int j, int k) { return cloud(i, j, k); };
    Decomposition d(MPI_COMM_WORLD, {n, n, n});
    const std::vector<double> sun_colour = {1.0, 0.8, 0.5}, source_colour = {0.2, 0.9, 2.0};
    const SourceSpec box{{1.5, 1.0, 1.25}, {3.5, 4.0, 3.0}, {}};
    // Bands `bands` of the scene; sun and source scaled by `sun_on`, `source_on`.
    auto run = [&](const std::vector<int>& bands, double sun_on, double source_on, Report& report) {
        Medium m = test::make_medium(d, h, band, rho);
        m.bands.assign(bands.size(), band);
        LightTransport lt = test::column_light(d, h, sun, 1.0, rho);
        lt.lights[0].E0.clear();
        SourceSpec src = box;
        for (int b : bands) {
            lt.lights[0].E0.push_back(sun_on * sun_colour[static_cast<size_t>(b)]);
            src.power.push_back(source_on * source_colour[static_cast<size_t>(b)]);
        }
        return solve(emitting_scene({n, n, n}, h, m.bands, {src}), d, m, lt, tol, report, false);
    };
    Report r3;
    const DiffuseSolution all = run({0, 1, 2}, 1.0, 1.0, r3);
    EXPECT_EQ(r3.values()["diffusion"]["solves"].get<int>(), 2);
    const auto& systems = r3.values()["diffusion"]["systems"];
    ASSERT_EQ(systems.size(), 2u);
    EXPECT_EQ(systems[0]["terms"], nlohmann::json::array({"sun"}));
    EXPECT_EQ(systems[1]["terms"], nlohmann::json::array({"sources[0]"}));
    for (int b = 0; b < 3; ++b) {
        Report r1, rs, re;
        const DiffuseSolution one = run({b}, 1.0, 1.0, r1);
        const DiffuseSolution sun_only = run({b}, 1.0, 0.0, rs), source_only = run({b}, 0.0, 1.0, re);
        const auto [diff, fmax] = test::max_diff(one.fluence[0], all.fluence[static_cast<size_t>(b)], d.local(), MPI_COMM_WORLD);
        double sum_diff = 0.0, src_max = 0.0;
        for_each_cell(d.local(), [&](int i, int j, int k) {
            sum_diff = std::max(sum_diff, std::abs(one.fluence[0](i, j, k) - sun_only.fluence[0](i, j, k) -
                                                   source_only.fluence[0](i, j, k)));
            src_max = std::max(src_max, source_only.fluence[0](i, j, k));
        });
        sum_diff = test::global_max(sum_diff, MPI_COMM_WORLD);
        src_max = test::global_max(src_max, MPI_COMM_WORLD);
        if (test::world_rank() == 0)
            std::printf("band %d: 3 bands in 2 solves vs alone %.2e, sun + source vs apart %.2e (of the peak)\n", b,
                        diff / fmax, sum_diff / fmax);
        EXPECT_GT(src_max, 0.05 * fmax) << "the source must matter in band " << b;
        EXPECT_LE(diff, 100 * tol * fmax) << "band " << b;
        EXPECT_LE(sum_diff, 100 * tol * fmax) << "band " << b;
    }
}

}  // namespace
}  // namespace nimbus
