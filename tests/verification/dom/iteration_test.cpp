// Iteration: 1 vs 2 ranks equal to the iteration tolerance (world against MPI_COMM_SELF, DSA and
// GMRES); the hard case of issue item 5 (cube of optical thickness 100, albedo 0.999 and 1): DSA
// and DSA-preconditioned GMRES converge in <= 30 iterations, while source iteration's spectral
// radius is about a, i.e. thousands of iterations (shown with a capped count); unpreconditioned
// GMRES for comparison; iterations and wall times printed; non-convergence is an Error; DSA's
// correction is exactly linear in the sweep's changes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/band_problem.h"
#include "solvers/dom/dom.h"
#include "solvers/dom/dsa.h"
#include "solvers/dom/iteration.h"
#include "solvers/light/sun_transmittance.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/dom/dom_world.h"

namespace nimbus {
namespace {

// A lumpy cloud in a 10 x 8 x 12 box, lit obliquely.
test::DomWorld cloud(MPI_Comm comm) {
    test::DomWorld w(comm, {10, 8, 12}, 0.5, BandOptics{"gray", 1.0, 0.95, 0.7});
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        const double r2 = std::pow(i - 4.5, 2) + std::pow(j - 3.5, 2) + std::pow(k - 5.5, 2);
        w.m.rho(i, j, k) = r2 < 20 ? 2.0 + 0.3 * ((i + 2 * j + 3 * k) % 4) : 0.0;
    });
    w.add_sun_from_top({0.0, 0.0, -1.0});  // vertical: tau_rho column sums below are exact
    Field<double>& tau = w.light.tau_rho[0];
    for_each_cell(w.d.local(), [&](int i, int j, int k) { tau(i, j, k) = 0.0; });
    // tau_rho = ∫ rho ds upward from the cell centre: needs the whole column, so recompute it
    // from the procedural density (identical on every rank).
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        auto rho = [&](int kk) {
            const double r2 = std::pow(i - 4.5, 2) + std::pow(j - 3.5, 2) + std::pow(kk - 5.5, 2);
            return r2 < 20 ? 2.0 + 0.3 * ((i + 2 * j + 3 * kk) % 4) : 0.0;
        };
        double t = 0.5 * rho(k);
        for (int kk = k + 1; kk < 12; ++kk) t += rho(kk);
        tau(i, j, k) = t * w.m.grid.h;
    });
    exchange_halo(tau, w.d);  // the light pass's contract
    return w;
}

// The angular set of the tests that drive the iteration directly: S4, Legendre order 3.
dom::AngularSet s4_l3() {
    DomOptions o;
    o.order = 4;
    o.legendre_order = 3;
    return dom::make_angular_set(o);
}

TEST(DomIteration, OneAndTwoRanksAgreeToTheTolerance) {
    for (const char* method : {"dsa", "gmres"}) {
        DomOptions o;
        o.order = 4;
        o.legendre_order = 3;
        o.tolerance = 1e-10;
        o.tile_rows = 3;
        o.iteration = method;
        test::DomWorld world = cloud(MPI_COMM_WORLD), self = cloud(MPI_COMM_SELF);
        DiffuseSolution a, b;
        make_dom_model(o)->solve(world.ctx(), a);
        make_dom_model(o)->solve(self.ctx(), b);
        const auto [diff, peak] = test::solution_difference(world.d, a, b);
        if (test::world_rank() == 0)
            std::printf("%s, 1 vs %d ranks: max diff %.3e of peak %.4f\n", method, test::world_size(), diff, peak);
        EXPECT_GT(peak, 0.0);
        EXPECT_LE(diff, 1e-8 * peak) << method;
    }
}

// The outer iterations sweep only the bounding box of the medium (TransportSweeper::region) and
// one last sweep covers the domain. The reference is the same problem with an extinction of
// 1e-300 /m in its empty cells, whose region is the whole domain: the fields agree everywhere,
// in the void around the cloud too, to the iteration's tolerance.
TEST(DomIteration, SweepingTheMediumsBoxGivesTheWholeDomainsAnswer) {
    test::DomWorld w = cloud(MPI_COMM_WORLD);
    const dom::AngularSet ang = s4_l3();
    dom::BandProblem boxed = dom::make_band_optics(w.m, 0, w.d.local(), ang, true);
    dom::add_light_sources(boxed, w.d, w.m, w.light, 0, ang);
    dom::BandProblem filled = boxed;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        if (filled.kappa(i, j, k) == 0.0) filled.kappa(i, j, k) = 1e-300;
    });
    sweep::SweepOptions opt;
    opt.tile_rows = 3;
    Box region;
    {
        const dom::TransportSweeper sweeper(w.d, ang, w.m.grid.h, opt, 1e-11);
        const std::optional<Box> r = sweeper.region(boxed.kappa, dom::source_rows(boxed));
        ASSERT_TRUE(r.has_value());
        region = *r;
        EXPECT_LT(region.cells(), w.d.global().cells() * 3 / 4);
        EXPECT_EQ(sweeper.region(filled.kappa, dom::source_rows(filled)), std::nullopt);
    }
    for (const char* method : {"dsa", "gmres"}) {
        auto solve = [&](const dom::BandProblem& p) {
            dom::TransportSweeper sweeper(w.d, ang, w.m.grid.h, opt, 1e-11);
            dom::SweepOutput out;
            const dom::IterationResult r = dom::iterate_band(w.d, sweeper, ang, p, method, 1e-10, 200, out, w.report);
            EXPECT_TRUE(r.converged) << method;
            return out;
        };
        const dom::SweepOutput a = solve(boxed), b = solve(filled);
        double v[3] = {0.0, 0.0, 0.0};  // max diff, peak, the peak outside the region (the last sweep's)
        for_each_cell(w.d.local(), [&](int i, int j, int k) {
            v[0] = std::max(v[0], std::abs(a.fluence(i, j, k) - b.fluence(i, j, k)));
            for (int c = 0; c < 3; ++c) v[0] = std::max(v[0], std::abs(a.flux(i, j, k, c) - b.flux(i, j, k, c)));
            v[1] = std::max(v[1], b.fluence(i, j, k));
            if (!region.contains(i, j, k)) v[2] = std::max(v[2], a.fluence(i, j, k));
        });
        MPI_Allreduce(MPI_IN_PLACE, v, 3, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        double leak[2] = {0.0, 0.0};
        for (size_t f = 0; f < 6; ++f) {
            leak[0] = std::max(leak[0], std::abs(a.leakage[f] - b.leakage[f]));
            leak[1] = std::max(leak[1], std::abs(b.leakage[f]));
        }
        if (test::world_rank() == 0)
            std::printf("%s: the box's sweeps against the whole domain's: max diff %.3e of peak %.4f (outside the box %.4f), "
                        "leakage %.3e of %.4f\n", method, v[0], v[1], v[2], leak[0], leak[1]);
        EXPECT_GT(v[2], 0.05 * v[1]) << method;
        EXPECT_LE(v[0], 1e-8 * v[1]) << method;
        EXPECT_LE(leak[0], 1e-8 * leak[1]) << method;
    }
}

using test::CubeRun;

// Cube of 16³ cells, optical thickness 100 along each axis, isotropic scattering, S4; a solve
// that fails must say it did not converge.
CubeRun thick_cube(double albedo, const std::string& method, int max_iterations) {
    CubeRun r = test::solve_thick_cube(16, 100.0, albedo, "step", method, max_iterations);
    if (!r.converged) {
        EXPECT_NE(r.error.find("did not converge"), std::string::npos) << r.error;
    }
    return r;
}

void print_cube_run(double albedo, const char* method, const CubeRun& r) {
    if (test::world_rank() == 0)
        std::printf("tau 100 cube, albedo %.3f, %-11s: %4d iterations%s, last change %.2e, %5d DSA linear "
                    "iterations (PFMG-PCG; GMRES: V-cycles), %.3f s\n", albedo, method, r.iterations, r.converged ? "" : " (capped)",
                    r.history.empty() ? 0.0 : r.history.back(), r.dsa_linear_iterations, r.seconds);
}

// max |a - b| / max b over owned cells, all ranks.
double max_rel_diff(const DiffuseSolution& a, const DiffuseSolution& b) {
    double diff = 0.0, peak = 0.0;
    for_each_cell(b.fluence[0].owned(), [&](int i, int j, int k) {
        diff = std::max(diff, std::abs(a.fluence[0](i, j, k) - b.fluence[0](i, j, k)));
        peak = std::max(peak, std::abs(b.fluence[0](i, j, k)));
    });
    MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &peak, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    return peak > 0 ? diff / peak : diff;
}

// Issue item 5: DSA and DSA-preconditioned GMRES within 30 iterations; unpreconditioned GMRES
// shown for comparison (all stop on the same relative change, 1e-6; gmres.h).
TEST(DomIteration, DsaAndPreconditionedGmresConvergeOnTheThickCube) {
    for (double a : {0.999, 1.0}) {
        const CubeRun dsa = thick_cube(a, "dsa", 30);
        const CubeRun gmres = thick_cube(a, "gmres", 30);
        const CubeRun plain = thick_cube(a, "gmres-plain", 100);
        print_cube_run(a, "dsa", dsa);
        print_cube_run(a, "gmres (DSA)", gmres);
        print_cube_run(a, "gmres-plain", plain);
        EXPECT_TRUE(dsa.converged) << "albedo " << a;
        EXPECT_TRUE(gmres.converged) << "albedo " << a;
        EXPECT_TRUE(plain.converged) << "albedo " << a;
        EXPECT_LE(dsa.iterations, 30);
        EXPECT_LE(gmres.iterations, 30);
        if (!dsa.converged || !gmres.converged || !plain.converged) continue;
        const double d_gmres = max_rel_diff(gmres.sol, dsa.sol), d_plain = max_rel_diff(plain.sol, dsa.sol);
        if (test::world_rank() == 0)
            std::printf("  max |fluence - DSA's| / peak: gmres %.2e, gmres-plain %.2e\n", d_gmres, d_plain);
        EXPECT_LE(d_gmres, 1e-5);
        // Unpreconditioned GMRES converges slowly (28-29 iterations), so its stop at a change of
        // 1e-6 leaves more of an error (2.5e-5 and 3.0e-5 measured); still the same answer.
        EXPECT_LE(d_plain, 1e-4);
    }
}

// Non-convergence is an Error on every rank, with the per-iteration history in the report.
TEST(DomIteration, GmresNonConvergenceIsAnErrorWithItsHistory) {
    for (const char* method : {"gmres", "gmres-plain"}) {
        const CubeRun r = thick_cube(1.0, method, 2);  // thick_cube checks the message
        EXPECT_FALSE(r.converged) << method;
        EXPECT_EQ(r.iterations, 2) << method;
        ASSERT_EQ(r.history.size(), 2u) << method;
        EXPECT_GT(r.history[1], 1e-6) << method;
    }
}

TEST(DomIteration, GmresDsaAndSourceIterationAgree) {
    DiffuseSolution sol[4];
    const char* methods[4] = {"source", "dsa", "gmres", "gmres-plain"};
    for (int q = 0; q < 4; ++q) {
        test::DomWorld w = cloud(MPI_COMM_WORLD);
        DomOptions o;
        o.order = 4;
        o.legendre_order = 3;
        o.tolerance = 1e-10;
        o.iteration = methods[q];
        make_dom_model(o)->solve(w.ctx(), sol[q]);
    }
    double diff = 0.0, peak = 0.0;
    for_each_cell(sol[0].fluence[0].owned(), [&](int i, int j, int k) {
        for (int q = 1; q < 4; ++q) diff = std::max(diff, std::abs(sol[q].fluence[0](i, j, k) - sol[0].fluence[0](i, j, k)));
        peak = std::max(peak, sol[0].fluence[0](i, j, k));
    });
    MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &peak, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (test::world_rank() == 0) std::printf("source vs dsa vs gmres vs gmres-plain: max diff %.3e of peak %.4f\n", diff, peak);
    EXPECT_LE(diff, 1e-7 * peak);
}

TEST(DomIteration, SourceIterationStallsOnTheThickCube) {
    const int cap = 200;
    for (double a : {0.999, 1.0}) {
        const CubeRun r = thick_cube(a, "source", cap);
        EXPECT_FALSE(r.converged);
        ASSERT_EQ(static_cast<int>(r.history.size()), cap);
        const double rho = r.history[cap - 1] / r.history[cap - 2];
        // Source iteration's error is about change · rho/(1 - rho): iterations until that is 1e-6.
        const double needed = cap + std::log(1e-6 * (1 - rho) / (rho * r.history[cap - 1])) / std::log(rho);
        if (test::world_rank() == 0)
            std::printf("tau 100 cube, albedo %.3f, source iteration: change %.2e after %d (%.3f s), ratio %.5f, "
                        "about %.0f iterations (%.1f s) needed for an error of 1e-6\n", a, r.history[cap - 1], cap,
                        r.seconds, rho, needed, needed * r.seconds / cap);
        EXPECT_GT(rho, 0.98);
        EXPECT_GT(needed, 1000);
    }
}

// The early stop of source iteration and DSA (iteration.h): a change that keeps setting new
// minima runs on, and so does one wandering at a floor; one that grew above kStallGrowth times
// its minimum and stayed there for kStallWindow iterations stops.
TEST(DomIteration, StallDetection) {
    using dom::kStallWindow;
    std::vector<double> slow, wavy, flat, diverging;
    for (int i = 0; i < 6 * kStallWindow; ++i) {
        slow.push_back(std::pow(0.99, i));                                      // source iteration, ratio 0.99
        wavy.push_back(std::pow(0.6, i / 6.0) * (1.5 + std::sin(i * std::acos(-1.0) / 3)));  // period 6
        flat.push_back(i < 10 ? std::pow(0.3, i) : 1e-5 * (1.5 + std::sin(i)));  // wandering at a floor
        diverging.push_back(i < 4 ? std::pow(0.3, i) : 0.07 * std::pow(1.3, i - 4));
        const std::vector<double> s(slow), w(wavy);
        EXPECT_FALSE(dom::stalled(s)) << i;
        EXPECT_FALSE(dom::stalled(w)) << i;
    }
    EXPECT_FALSE(dom::stalled(flat));  // at a floor (e.g. round-off): max_iterations decides
    std::vector<double> d(diverging.begin(), diverging.begin() + 2 * kStallWindow - 1);
    EXPECT_FALSE(dom::stalled(d));  // too short to tell
    d.push_back(diverging[2 * kStallWindow - 1]);
    EXPECT_TRUE(dom::stalled(d));
}

// blew_up (iteration.h): the norm past kBlowUp times the first, or not finite; converging
// sequences (growth ~1/(1 - rho) from the first iterate) stay far below.
TEST(DomIteration, BlowUpDetection) {
    EXPECT_FALSE(dom::blew_up({}));
    EXPECT_FALSE(dom::blew_up({0.0, 5.0}));  // nothing to compare with
    std::vector<double> converging, diverging;
    for (int i = 0; i < 2000; ++i) {
        converging.push_back(1.0 - std::pow(0.999, i + 1));  // source iteration at rho 0.999
        EXPECT_FALSE(dom::blew_up(converging)) << i;
    }
    for (int i = 0; i < 40; ++i) diverging.push_back(std::pow(3.0, i));
    std::vector<double> d;
    for (double x : diverging) {
        d.push_back(x);
        if (dom::blew_up(d)) break;
    }
    EXPECT_EQ(d.size(), 27u);  // 3^26 = 2.5e12 > 1e12 > 3^25
    EXPECT_TRUE(dom::blew_up({1.0, std::numeric_limits<double>::infinity()}));
    EXPECT_TRUE(dom::blew_up({1.0, std::numeric_limits<double>::quiet_NaN()}));
}

// The divergence the QA sweep found (thirtieth session): strong backscattering (g = -0.99) with a
// Legendre order beyond what S4 integrates (L = 8) grows the fluence ~3x per iteration at a flat
// relative change of ~0.66, which the stall test does not see; the fluence overflowed after ~325
// iterations and the Inf/NaN change passed for convergence. Now: an Error that says it diverges.
TEST(DomIteration, GeometricBlowUpIsAnError) {
    for (const char* method : {"source", "dsa"}) {
        const CubeRun r = test::solve_thick_cube(8, 8.0, 0.99, "step", method, 500, -0.99, 8);
        EXPECT_FALSE(r.converged) << method;
        EXPECT_NE(r.error.find("diverges"), std::string::npos) << method << ": " << r.error;
        EXPECT_NE(r.error.find("legendre_order <= 3"), std::string::npos) << method << ": " << r.error;
        EXPECT_LT(r.iterations, 60) << method;  // ~27 at a growth of 3 per iteration
        if (test::world_rank() == 0)
            std::printf("g -0.99, S4 L8, %s: %s\n", method, r.error.substr(0, 160).c_str());
    }
}

// Negative fluence from the truncated phase function's lobes (g = -0.9 at S4 L3: down to -2.5% of
// the peak) is reported per band (and warned about); S8 L7 stays above -1e-3 of the peak (-3e-4),
// and the forward-scattering sphere has none.
TEST(DomIteration, NegativeFluenceIsReported) {
    struct Case {
        double g;
        int order, legendre_order;
        bool negative;
    };
    for (const Case c : {Case{-0.9, 4, 3, true}, Case{-0.9, 8, 7, false}, Case{0.7, 4, 3, false}}) {
        // A sphere of optical diameter 4 in a 16 x 16 x 12 box, lit obliquely (the light pass
        // computes its transmittance): empty cells reached from it only at the scattering angles
        // of the truncated phase function's negative lobe get negative fluence (as
        // scenes/sphere_ground.toml at g = -0.9, found by the QA sweep).
        test::DomWorld w(MPI_COMM_WORLD, {16, 16, 12}, 0.5, BandOptics{"gray", 1.0, 0.9, c.g});
        for_each_cell(w.d.local(), [&](int i, int j, int k) {
            const double r2 = std::pow(i - 7.5, 2) + std::pow(j - 7.5, 2) + std::pow(k - 5.5, 2);
            w.m.rho(i, j, k) = r2 < 16 ? 1.0 : 0.0;
        });
        w.light = compute_light_transport(w.d, w.m, {DirectionalLight{"sun", normalized(Vec3{0.5, 0.3, -0.81}), {1.0}}},
                                          w.report);
        DomOptions o;
        o.order = c.order;
        o.legendre_order = c.legendre_order;
        o.iteration = "gmres";
        DiffuseSolution sol;
        make_dom_model(o)->solve(w.ctx(), sol);
        double min = 0.0, max = 0.0;
        for_each_cell(sol.fluence[0].owned(), [&](int i, int j, int k) {
            min = std::min(min, sol.fluence[0](i, j, k));
            max = std::max(max, sol.fluence[0](i, j, k));
        });
        MPI_Allreduce(MPI_IN_PLACE, &min, 1, MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD);
        MPI_Allreduce(MPI_IN_PLACE, &max, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        const auto& rec = w.report.values()["dom"];
        const bool reported = rec.contains("negative_fluence");
        if (test::world_rank() == 0)
            std::printf("g %.1f, S%d L%d: min/max fluence %.2e, reported %d\n", c.g, c.order, c.legendre_order,
                        min / max, reported);
        EXPECT_EQ(reported, c.negative) << c.g << " S" << c.order;
        EXPECT_EQ(min < -1e-3 * max, c.negative) << c.g << " S" << c.order;
        if (reported) {
            EXPECT_GT(rec["negative_fluence"]["gray"]["cells"].get<int>(), 0);
            EXPECT_DOUBLE_EQ(rec["negative_fluence"]["gray"]["min"].get<double>(), min);
        }
    }
}

// The iteration tells its monitor of every iteration, with the history so far (source iteration
// with DSA and GMRES alike).
TEST(DomIteration, MonitorSeesEveryIteration) {
    for (const char* method : {"dsa", "gmres"}) {
        test::DomWorld w = cloud(MPI_COMM_WORLD);
        const dom::AngularSet ang = s4_l3();
        dom::BandProblem p = dom::make_band_optics(w.m, 0, w.d.local(), ang, true);
        dom::add_light_sources(p, w.d, w.m, w.light, 0, ang);
        dom::TransportSweeper sweeper(w.d, ang, w.m.grid.h, {}, 1e-7);
        dom::SweepOutput out;
        std::vector<std::vector<double>> seen;
        const auto r = dom::iterate_band(w.d, sweeper, ang, p, method, 1e-6, 50, out, w.report,
                                         [&](const std::vector<double>& h) { seen.push_back(h); });
        EXPECT_TRUE(r.converged) << method;
        ASSERT_EQ(seen.size(), r.history.size()) << method;
        ASSERT_GE(seen.size(), 2u) << method;
        for (size_t i = 0; i < seen.size(); ++i)
            EXPECT_EQ(seen[i], std::vector<double>(r.history.begin(), r.history.begin() + static_cast<std::ptrdiff_t>(i + 1)))
                << method << ", call " << i;
    }
}

// DSA corrects the current as well as the isotropic error (dsa.h). Here (16³ cube, tau 20,
// albedo 0.99, S4, P3, tolerance 1e-6: scenes/dense_cube.toml's optics at g = 0.85, -0.5, -0.9)
// DSA takes 14, 11 and 35 iterations and DSA-preconditioned GMRES 8, 7 and 18. With the
// isotropic correction alone (the current's source and update dropped, as before the
// twenty-sixth session) DSA took 23 and 37 and stalled at g = -0.9 (40 iterations, the change
// settling near 1.8), GMRES 13, 9 and 19.
TEST(DomIteration, DsaWithTheCurrentConvergesOnForwardAndBackscattering) {
    struct Case {
        double g;
        int max_iterations, max_gmres_iterations;
    };
    for (const Case c : {Case{0.85, 18, 10}, Case{-0.5, 14, 8}, Case{-0.9, 38, 20}}) {
        const CubeRun dsa = test::solve_thick_cube(16, 20.0, 0.99, "step", "dsa", 60, c.g, 3);
        const CubeRun gmres = test::solve_thick_cube(16, 20.0, 0.99, "step", "gmres", 60, c.g, 3);
        if (test::world_rank() == 0)
            std::printf("tau 20 cube, a 0.99, g %5.2f: dsa %d iterations (%.2f s), gmres %d\n", c.g, dsa.iterations,
                        dsa.seconds, gmres.iterations);
        ASSERT_TRUE(dsa.converged) << "g " << c.g << ": " << dsa.error;
        ASSERT_TRUE(gmres.converged) << "g " << c.g << ": " << gmres.error;
        EXPECT_LE(dsa.iterations, c.max_iterations) << "g " << c.g;
        EXPECT_LE(gmres.iterations, c.max_gmres_iterations) << "g " << c.g;
        EXPECT_LE(max_rel_diff(dsa.sol, gmres.sol), 1e-5) << "g " << c.g;
    }
}

}  // namespace
}  // namespace nimbus

namespace nimbus {
namespace {

// DSA's correction is one fixed linear map of the sweep's changes (dsa.h: kVCycles PFMG
// V-cycles from zero, the current's filter a fixed cycle too), which GMRES's preconditioner
// needs: for changes (r0, r1) and (s0, s1), corr(2 r - 3 s) = 2 corr(r) - 3 corr(s) to round-off,
// on the lumpy cloud with its empty cells, and a zero change gives a zero correction with no
// cycle run. A solve to a residual tolerance (PCG, as DSA's source iteration used before) is not
// additive: its Krylov polynomial depends on the right-hand side (it failed this test at 1e-3).
TEST(DomDsa, CorrectionIsALinearMapOfTheChanges) {
    test::DomWorld w = cloud(MPI_COMM_WORLD);
    const dom::AngularSet ang = s4_l3();
    dom::BandProblem p = dom::make_band_optics(w.m, 0, w.d.local(), ang, true);
    dom::DiffusionSynthetic dsa(w.d, p);
    const Box& own = w.d.local();
    // Two unrelated smooth-plus-rough changes (deterministic in the global cell index).
    auto change = [&](int seed, Field<double>& r0, Field<double>& r1) {
        r0 = Field<double>(own, 0, 1, 0.0);
        r1 = Field<double>(own, 0, 3, 0.0);
        for_each_cell(own, [&](int i, int j, int k) {
            const double v = std::sin(0.7 * i + 1.3 * seed) * std::cos(0.5 * j - seed) + 0.1 * ((i * 7 + j * 3 + k * 5 + seed) % 11);
            r0(i, j, k) = v;
            for (int c = 0; c < 3; ++c) r1(i, j, k, c) = std::cos(0.3 * k + c + seed) - 0.05 * ((i + 2 * c + seed) % 5);
        });
    };
    Field<double> r0, r1, s0, s1, m0, m1;
    change(1, r0, r1);
    change(2, s0, s1);
    m0 = Field<double>(own, 0, 1, 0.0);
    m1 = Field<double>(own, 0, 3, 0.0);
    for_each_cell(own, [&](int i, int j, int k) {
        m0(i, j, k) = 2.0 * r0(i, j, k) - 3.0 * s0(i, j, k);
        for (int c = 0; c < 3; ++c) m1(i, j, k, c) = 2.0 * r1(i, j, k, c) - 3.0 * s1(i, j, k, c);
    });
    auto run = [&](const Field<double>& a0, const Field<double>& a1, Field<double>& delta, Field<double>& current) {
        EXPECT_EQ(dsa.solve(a0, &a1), dom::DiffusionSynthetic::kVCycles);
        delta = dsa.last_correction();
        current = dsa.last_current_correction();
    };
    Field<double> dr, fr, ds, fs, dm, fm;
    run(r0, r1, dr, fr);
    run(s0, s1, ds, fs);
    run(m0, m1, dm, fm);
    double diff = 0.0, peak = 0.0, cdiff = 0.0, cpeak = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        const double want = 2.0 * dr(i, j, k) - 3.0 * ds(i, j, k);
        diff = std::max(diff, std::abs(dm(i, j, k) - want));
        peak = std::max(peak, std::abs(want));
        for (int c = 0; c < 3; ++c) {
            const double wc = 2.0 * fr(i, j, k, c) - 3.0 * fs(i, j, k, c);
            cdiff = std::max(cdiff, std::abs(fm(i, j, k, c) - wc));
            cpeak = std::max(cpeak, std::abs(wc));
        }
    });
    double v[4] = {diff, peak, cdiff, cpeak};
    MPI_Allreduce(MPI_IN_PLACE, v, 4, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (test::world_rank() == 0)
        std::printf("DSA linearity: fluence %.2e of %.3e, current %.2e of %.3e\n", v[0], v[1], v[2], v[3]);
    ASSERT_GT(v[1], 0.0);
    ASSERT_GT(v[3], 0.0);
    EXPECT_LE(v[0], 1e-12 * v[1]);
    EXPECT_LE(v[2], 1e-12 * v[3]);
    // A vanishing change: no cycle, zero corrections.
    Field<double> z0(own, 0, 1, 0.0), z1(own, 0, 3, 0.0);
    EXPECT_EQ(dsa.solve(z0, &z1), 0);
    double zmax = 0.0;
    for_each_cell(own, [&](int i, int j, int k) {
        zmax = std::max(zmax, std::abs(dsa.last_correction()(i, j, k)));
        for (int c = 0; c < 3; ++c) zmax = std::max(zmax, std::abs(dsa.last_current_correction()(i, j, k, c)));
    });
    EXPECT_EQ(zmax, 0.0);
}

}  // namespace
}  // namespace nimbus
