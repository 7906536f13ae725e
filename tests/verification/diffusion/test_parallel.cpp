// (d) Decomposition invariance: the model on the world communicator (slabs along z) and on
// MPI_COMM_SELF (each rank solves the whole domain) agree to the solver tolerance.
// (e) The PETSc path (KSP CG + BoomerAMG, or PCMG through model.diffusion.petsc_options) and
// every hypre solver agree with PFMG-PCG.
// Also: non-convergence is an error that shows the residual history (issue 4 item 2), bad
// PETSc options are one collective error naming the option, and the solve region is the
// bounding box of the full cells plus the margin (item 4).
#include <gtest/gtest.h>
#include <_hypre_utilities.h>  // hypre_error_handler: flags an error as hypre does inside

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>

#include "tests/verification/diffusion/diffusion_test_util.h"
#include "solvers/diffusion/diffusion.h"
#include "src/core/error.h"
#include "solvers/diffusion/hypre_struct.h"
#include "solvers/diffusion/solve_diffusion.h"
#include "solvers/diffusion/sources.h"
#include "src/physics/band_groups.h"
#include "src/scene/medium.h"
#include "tests/support/expect_collective_error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

const BandOptics kBand{"gray", 3.0, 0.9, 0.85};
const Vec3 kSun = normalized(Vec3{0.3, 0.2, -1.0});
constexpr int kN = 24;
constexpr double kH = 0.25;

double cumulus(int i, int j, int k) {
    static const ProceduralDensity density(MediumSpec{}, {kN, kN, kN});
    return density(i, j, k);
}

DiffuseSolution solve_on(MPI_Comm comm, const std::string& solver, double tol, Report& report,
                         std::unique_ptr<Decomposition>& d) {
    d = std::make_unique<Decomposition>(comm, Int3{kN, kN, kN});
    DiffusionOptions opt;
    opt.solver = solver;
    opt.tolerance = tol;
    opt.max_iterations = 2000;  // stand-alone PFMG is slow on a cloud's tenuous edge
    auto model = make_diffusion_model(opt);
    return test::run_model(*model, *d, kH, kBand, cumulus, kSun, report);
}

// A sphere of radius 9 cells centred in an n³ grid (n odd, so that PETSc can coarsen it).
double sphere_in(int n, int i, int j, int k) {
    const double c = 0.5 * n, x = i + 0.5 - c, y = j + 0.5 - c, z = k + 0.5 - c;
    return x * x + y * y + z * z <= 81.0 ? 1.0 : 0.0;
}

// With ||b - A x|| <= tol ||b||, two solutions differ by at most ~cond(A) tol, which is what
// is checked (100 tol). Measured: 1.9e-16 relative on 2 and 3 ranks at tol = 1e-10 (hypre's
// PFMG-PCG takes the same iterates on any split of this grid, to round-off); the bound is the
// guarantee, not the measurement.
TEST(DiffusionParallel, WorldEqualsSelf) {
    const double tol = 1e-10;
    Report rw, rs;
    std::unique_ptr<Decomposition> dw, ds;
    const auto world = solve_on(MPI_COMM_WORLD, "pfmg-pcg", tol, rw, dw);
    const auto self = solve_on(MPI_COMM_SELF, "pfmg-pcg", tol, rs, ds);
    const auto [diff, umax] = test::max_diff(world.fluence[0], self.fluence[0], dw->local(), MPI_COMM_WORLD);
    if (test::world_rank() == 0) std::printf("world vs self: max |diff| / max = %.2e\n", diff / umax);
    EXPECT_GT(umax, 0.0);
    EXPECT_LE(diff, 100 * tol * umax);
    // Region of the solve: the cloud's bounding box + margin, the same on both.
    EXPECT_EQ(rw.values()["diffusion"]["region"], rs.values()["diffusion"]["region"]);
}

TEST(DiffusionParallel, AllSolversAndPetscAgree) {
    const double tol = 1e-10;
    Report r0;
    std::unique_ptr<Decomposition> d0;
    const auto ref = solve_on(MPI_COMM_WORLD, "pfmg-pcg", tol, r0, d0);
    for (const std::string solver : {"pfmg", "smg", "smg-pcg", "petsc"}) {
        Report r;
        std::unique_ptr<Decomposition> d;
        const auto sol = solve_on(MPI_COMM_WORLD, solver, tol, r, d);
        const auto [diff, umax] = test::max_diff(ref.fluence[0], sol.fluence[0], d->local(), MPI_COMM_WORLD);
        const int its = r.values()["diffusion"]["systems"][0]["iterations"].get<int>();
        if (test::world_rank() == 0)
            std::printf("%-8s vs pfmg-pcg: max |diff| / max = %.2e, %d iterations\n", solver.c_str(),
                        diff / umax, its);
        EXPECT_LE(diff, 100 * tol * umax) << solver;
    }
}

// PCMG on the DMDA (3 levels, Galerkin coarse operators) through model.diffusion.petsc_options:
// the same answer as PFMG-PCG, and not BoomerAMG's iteration count (the options took effect).
TEST(DiffusionParallel, PetscGeometricMultigridAgrees) {
    constexpr int n = 25;  // n - 1 divisible by 4: PETSc coarsens the DMDA twice
    const double tol = 1e-10;
    auto solve = [&](const std::string& solver, const std::string& petsc_options, Report& report) {
        Decomposition d(MPI_COMM_WORLD, {n, n, n});
        DiffusionOptions opt;
        opt.solver = solver;
        opt.tolerance = tol;
        opt.petsc_options = petsc_options;
        auto model = make_diffusion_model(opt);
        auto sol = test::run_model(*model, d, kH, kBand, [n](int i, int j, int k) { return sphere_in(n, i, j, k); },
                                   kSun, report);
        return std::make_pair(std::move(sol), d.local());
    };
    Report r_ref, r_amg, r_mg;
    const auto [ref, box] = solve("pfmg-pcg", "", r_ref);
    const auto [amg, box_amg] = solve("petsc", "", r_amg);
    const auto [mg, box_mg] = solve("petsc", "-diffusion_pc_type mg -diffusion_pc_mg_levels 3 -diffusion_pc_mg_galerkin both",
                                    r_mg);
    const int its_amg = r_amg.values()["diffusion"]["systems"][0]["iterations"].get<int>();
    const int its_mg = r_mg.values()["diffusion"]["systems"][0]["iterations"].get<int>();
    const auto [diff, umax] = test::max_diff(ref.fluence[0], mg.fluence[0], box, MPI_COMM_WORLD);
    if (test::world_rank() == 0)
        std::printf("PCMG vs pfmg-pcg: max |diff| / max = %.2e; CG iterations: PCMG %d, BoomerAMG %d\n",
                    diff / umax, its_mg, its_amg);
    EXPECT_GT(umax, 0.0);
    EXPECT_LE(diff, 100 * tol * umax);
    EXPECT_NE(its_mg, its_amg);
}

// Three bands with equal optics lit by a white sun and a blue "sky" light from another
// direction (band_groups.h): 2 solves (one per light colour), and each band equals the band
// solved alone (1 rhs) to the solver tolerance.
TEST(DiffusionParallel, BandsShareSolvesByLightColour) {
    const double tol = 1e-11;
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    const Vec3 w_sky = normalized(Vec3{-0.5, 0.1, -1.0});
    const std::vector<std::array<double, 2>> colour = {{1.0, 0.03}, {0.95, 0.05}, {0.85, 0.09}};  // sun, sky
    auto light_of = [&](const std::vector<int>& bands) {
        LightTransport sun = test::column_light(d, kH, kSun, 1.0, cumulus);
        LightTransport sky = test::column_light(d, kH, w_sky, 1.0, cumulus);  // tau exact enough: any field works
        LightTransport lt;
        lt.lights = {sun.lights[0], sky.lights[0]};
        lt.lights[1].name = "sky";
        lt.lights[0].E0.clear();
        lt.lights[1].E0.clear();
        for (int b : bands) lt.lights[0].E0.push_back(colour[b][0]), lt.lights[1].E0.push_back(colour[b][1]);
        lt.tau_rho = {std::move(sun.tau_rho[0]), std::move(sky.tau_rho[0])};
        return lt;
    };
    auto solve = [&](const std::vector<int>& bands, Report& report) {
        Medium m = test::make_medium(d, kH, kBand, cumulus);
        m.bands.assign(bands.size(), kBand);
        for (size_t b = 0; b < bands.size(); ++b) m.bands[b].name = "band" + std::to_string(bands[b]);
        const LightTransport lt = light_of(bands);
        DiffusionOptions opt;
        opt.tolerance = tol;
        auto model = make_diffusion_model(opt);
        Scene scene;
        DiffuseSolution sol;
        model->solve(SolveContext{scene, d, m, lt, report}, sol);
        return sol;
    };
    Report r3;
    const DiffuseSolution all = solve({0, 1, 2}, r3);
    EXPECT_EQ(r3.values()["diffusion"]["solves"].get<int>(), 2);
    // The report says which light each solve is for and which bands use it.
    const auto& systems = r3.values()["diffusion"]["systems"];
    ASSERT_EQ(systems.size(), 2u);
    for (size_t e = 0; e < 2; ++e) {
        EXPECT_EQ(systems[e]["matrix"].get<int>(), 0);
        EXPECT_EQ(systems[e]["rhs"].get<size_t>(), e);
        EXPECT_EQ(systems[e]["bands"], nlohmann::json::array({"band0", "band1", "band2"}));
        EXPECT_FALSE(systems[e].contains("limiter_iteration"));
    }
    EXPECT_EQ(systems[0]["terms"], nlohmann::json::array({"sun"}));
    EXPECT_EQ(systems[1]["terms"], nlohmann::json::array({"sky"}));
    for (int b = 0; b < 3; ++b) {
        Report r1;
        const DiffuseSolution one = solve({b}, r1);
        EXPECT_EQ(r1.values()["diffusion"]["solves"].get<int>(), 1);
        const auto [diff, umax] = test::max_diff(one.fluence[0], all.fluence[static_cast<size_t>(b)], d.local(), MPI_COMM_WORLD);
        if (test::world_rank() == 0) std::printf("band %d: 3 bands in 2 solves vs alone: max |diff| / max = %.2e\n", b, diff / umax);
        EXPECT_GT(umax, 0.0);
        EXPECT_LE(diff, 100 * tol * umax) << "band " << b;
    }
}

// A grid PETSc cannot coarsen three times is refused with an Error (it used to crash).
TEST(DiffusionParallel, PetscMultigridOnAnUncoarsenableGridIsAnError) {
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});  // 24: 23 is odd
    DiffusionOptions opt;
    opt.solver = "petsc";
    opt.petsc_options = "-diffusion_pc_type mg -diffusion_pc_mg_levels 3";
    auto model = make_diffusion_model(opt);
    Report report;
    EXPECT_THROW(test::run_model(*model, d, kH, kBand, cumulus, kSun, report), Error);
}

// A bad model.diffusion.petsc_options is one Error, the same on every rank, that names the
// option and gives PETSc's message: from the model's check (before the light pass), and from the
// solve on its own. (PETSc's own error handler printed a traceback and made every rank but 0
// sleep 10 s and exit(0) without MPI_Finalize.) An option that nothing reads is refused after
// the first solve, by name.
TEST(DiffusionParallel, BadPetscOptionsAreOneCollectiveErrorNamingTheOption) {
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    const Medium m = test::make_medium(d, kH, kBand, cumulus);
    const Scene scene;
    DiffusionOptions opt;
    opt.solver = "petsc";
    opt.petsc_options = "-diffusion_ksp_type cg -diffusion_pc_type nonexistent";
    auto model = make_diffusion_model(opt);
    test::expect_collective_error([&] { model->check(scene, d, m); },
                                  "model.diffusion.petsc_options: PETSc rejected '-diffusion_pc_type nonexistent': "
                                  "Unable to find requested PC type nonexistent");
    Report report;
    test::expect_collective_error([&] { test::run_model(*model, d, kH, kBand, cumulus, kSun, report); },
                                  "KSPSetFromOptions (model.diffusion.petsc_options = '-diffusion_ksp_type cg "
                                  "-diffusion_pc_type nonexistent') failed with PETSc error 86: Unable to find "
                                  "requested PC type nonexistent");
    opt.petsc_options = "-pc_type jacobi";
    test::expect_collective_error([&] { make_diffusion_model(opt)->check(scene, d, m); },
                                  "'-pc_type' lacks the prefix of the solver's options, -diffusion_");
    opt.petsc_options = "-diffusion_pc_typo jacobi";
    auto typo = make_diffusion_model(opt);
    typo->check(scene, d, m);
    test::expect_collective_error([&] { test::run_model(*typo, d, kH, kBand, cumulus, kSun, report); },
                                  "model.diffusion.petsc_options: PETSc did not use '-diffusion_pc_typo jacobi'");
    // The stopping test belongs to model.diffusion.tolerance and max_iterations.
    opt.petsc_options = "-diffusion_pc_type jacobi -diffusion_ksp_rtol 1e-2";
    test::expect_collective_error([&] { make_diffusion_model(opt)->check(scene, d, m); },
                                  "model.diffusion.petsc_options: '-diffusion_ksp_rtol' is set by "
                                  "model.diffusion.tolerance");
    opt.petsc_options = "-diffusion_ksp_norm_type none";  // no norm: PETSc would run to max_it unchecked
    test::expect_collective_error([&] { make_diffusion_model(opt)->check(scene, d, m); },
                                  "'-diffusion_ksp_norm_type' is set by model.diffusion.tolerance");
    opt.petsc_options = "-diffusion_ksp_max_it 3";
    test::expect_collective_error([&] { make_diffusion_model(opt)->check(scene, d, m); },
                                  "'-diffusion_ksp_max_it' is set by model.diffusion.max_iterations");
}

// A hypre failure on one rank (here a memory error flagged on the last rank, as hypre's
// allocator flags one) is one Error on every rank at the next collective hypre call, naming
// the call and hypre's description; the flag is cleared, so the next solve works.
TEST(DiffusionParallel, HypreFailureOnOneRankIsOneCollectiveError) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const Box box{{0, 0, 4 * rank}, {4, 4, 4 * rank + 4}};
    diffusion::hypre::Grid grid(MPI_COMM_WORLD, box, {0, 0, 0});
    if (rank == size - 1) hypre_error_handler(__FILE__, __LINE__, HYPRE_ERROR_MEMORY, nullptr);
    test::expect_collective_error([&] { diffusion::hypre::Vector v(MPI_COMM_WORLD, grid); },
                                  "diffusion: hypre's StructVectorInitialize failed (error 2: [Memory error] )");
    Report report;
    std::unique_ptr<Decomposition> d;
    const DiffuseSolution u = solve_on(MPI_COMM_WORLD, "pfmg-pcg", 1e-8, report, d);
    const std::vector<double> local = u.fluence[0].owned_values();
    EXPECT_GT(test::global_max(*std::max_element(local.begin(), local.end()), MPI_COMM_WORLD), 0.0);
}

// A system with more cells than hypre's 32-bit integers count (a 1300³ solve region, here split
// over the ranks) is one Error on every rank before hypre is called, not a wrapped size.
TEST(DiffusionParallel, HypreRefusesASystemBeyondItsIntegers) {
    const int rank = test::world_rank(), size = test::world_size();
    const int n = 1300, lo = n * rank / size, hi = n * (rank + 1) / size;
    test::expect_collective_error(
        [&] { diffusion::hypre::Grid grid(MPI_COMM_WORLD, Box{{0, 0, lo}, {n, n, hi}}, {0, 0, 0}); },
        "hypre: the structured system has 2197000000 cells, more than this hypre build's integers hold");
    // Just below the limit the check passes (hypre only records the extents here).
    const int m = 1290;  // 2 146 689 000 cells < 2^31 - 1
    diffusion::hypre::Grid ok(MPI_COMM_WORLD, Box{{0, 0, m * rank / size}, {m, m, m * (rank + 1) / size}}, {0, 0, 0});
}

// Too few iterations: an Error on every rank whose message gives the residual history.
TEST(DiffusionParallel, NonConvergenceIsAnErrorWithTheResidualHistory) {
    for (const std::string solver : {"pfmg-pcg", "smg", "petsc"}) {
        Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
        DiffusionOptions opt;
        opt.solver = solver;
        opt.tolerance = 1e-12;
        opt.max_iterations = 2;
        auto model = make_diffusion_model(opt);
        Report report;
        std::string what;
        try {
            test::run_model(*model, d, kH, kBand, cumulus, kSun, report);
        } catch (const Error& e) {
            what = e.what();
        }
        EXPECT_NE(what.find("did not reach the relative residual"), std::string::npos) << solver << ": " << what;
        EXPECT_NE(what.find("history"), std::string::npos) << solver << ": " << what;
        // The history lists each iteration's residual: "1: <value>" appears.
        EXPECT_NE(what.find("1: "), std::string::npos) << solver << ": " << what;
    }
}

// The solve region is the bounding box of the cells with density grown by the margin and
// clipped to the domain, on any decomposition; the report gives it. The margin adds only empty
// cells, so it changes the cost and not the answer: the transport-length cap comes from the
// cloud's own bounding box (before, from the grown region: 4% apart between margins 0 and 2).
TEST(DiffusionParallel, SolveRegionIsTheBoundingBoxPlusMargin) {
    const double tol = 1e-10;
    int lo[3] = {kN, kN, kN}, hi[3] = {0, 0, 0};
    for (int k = 0; k < kN; ++k)
        for (int j = 0; j < kN; ++j)
            for (int i = 0; i < kN; ++i) {
                if (!(cumulus(i, j, k) > 0.0)) continue;
                const int c[3] = {i, j, k};
                for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a] + 1);
            }
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    std::optional<DiffuseSolution> first;
    double first_floor = 0.0;
    for (const int margin : {0, 2, 30}) {
        DiffusionOptions opt;
        opt.margin = margin;
        opt.tolerance = tol;
        auto model = make_diffusion_model(opt);
        Report report;
        DiffuseSolution sol = test::run_model(*model, d, kH, kBand, cumulus, kSun, report);
        const double floor = report.values()["diffusion"]["kappa_tr_floor"].get<double>();
        if (!first) {
            first = std::move(sol);
            first_floor = floor;
        } else {
            EXPECT_EQ(floor, first_floor) << "margin " << margin;
            const auto [diff, umax] = test::max_diff(first->fluence[0], sol.fluence[0], d.local(), MPI_COMM_WORLD);
            EXPECT_GT(umax, 0.0);
            EXPECT_LE(diff, 100 * tol * umax) << "margin " << margin << " against 0";
        }
        const auto& region = report.values()["diffusion"]["region"];
        std::int64_t cells = 1;
        for (int a = 0; a < 3; ++a) {
            const int want_lo = std::max(0, lo[a] - margin), want_hi = std::min(kN, hi[a] + margin);
            EXPECT_EQ(region["lo"][a].get<int>(), want_lo) << "margin " << margin << ", axis " << a;
            EXPECT_EQ(region["hi"][a].get<int>(), want_hi) << "margin " << margin << ", axis " << a;
            cells *= want_hi - want_lo;
        }
        EXPECT_EQ(region["cells"].get<std::int64_t>(), cells);
    }
    // The cumulus does not fill the grid: the region is a real restriction.
    EXPECT_LT((hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]), kN * kN * kN);
}


// make_problem puts the right-hand sides' fields (Q0, G, escape flux) on the rank's part of the
// full cells' bounding box (DiffusionProblem::rhs_within), G's ghost layer filled across ranks
// within it: the solution is the same as with the fields on the whole rank box.
TEST(DiffusionParallel, RightHandSidesLiveOnTheCloudsBox) {
    Box cloud{{kN, kN, kN}, {0, 0, 0}};
    for_each_cell(Box{{0, 0, 0}, {kN, kN, kN}}, [&](int i, int j, int k) {
        if (!(cumulus(i, j, k) > 0.0)) return;
        const int c[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) cloud.lo[a] = std::min(cloud.lo[a], c[a]), cloud.hi[a] = std::max(cloud.hi[a], c[a] + 1);
    });
    ASSERT_LT(cloud.cells(), kN * kN * kN);  // a real restriction
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    const Medium m = test::make_medium(d, kH, kBand, cumulus);
    const LightTransport light = test::column_light(d, kH, kSun, 1.0, cumulus);
    const auto groups = group_bands(m.bands, term_strengths(light.lights, {}, m.nbands()));
    const diffusion::DiffusionProblem p = diffusion::make_problem(d, m, light, {}, groups[0], true);
    EXPECT_EQ(p.rhs_within, cloud);
    const Box own = d.local().intersect(cloud);
    ASSERT_EQ(p.Q0.size(), 1u);
    EXPECT_EQ(p.Q0[0].owned(), own);
    EXPECT_EQ(p.G[0].owned(), own);
    EXPECT_EQ(p.G[0].ghost(), 1);
    EXPECT_EQ(p.escape_flux[0].owned(), own);
    // The same problem with its right-hand side copied onto the whole rank box.
    diffusion::DiffusionProblem whole = p;
    whole.rhs_within = Box{};
    whole.Q0 = {Field<double>(d.local(), 0, 1, 0.0)};
    whole.G = {Field<double>(d.local(), 1, 3, 0.0)};
    whole.escape_flux = {Field<double>(d.local(), 0, 3, 0.0)};
    double q0_sum = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (!(p.kappa_tr(i, j, k) > 0.0)) return;
        ASSERT_TRUE(own.contains(i, j, k)) << i << " " << j << " " << k;
        whole.Q0[0](i, j, k) = p.Q0[0](i, j, k);
        q0_sum += p.Q0[0](i, j, k);
        for (int c = 0; c < 3; ++c) {
            whole.G[0](i, j, k, c) = p.G[0](i, j, k, c);
            whole.escape_flux[0](i, j, k, c) = p.escape_flux[0](i, j, k, c);
        }
    });
    EXPECT_GT(test::global_sum(q0_sum, MPI_COMM_WORLD), 0.0);
    diffusion::exchange_rhs_halo(whole, whole.G[0], d);
    DiffusionOptions opt;
    opt.tolerance = 1e-10;
    Report r1, r2;
    const diffusion::DiffusionResult a = diffusion::solve_diffusion(d, p, opt, r1);
    const diffusion::DiffusionResult b = diffusion::solve_diffusion(d, whole, opt, r2);
    // The same system and right-hand side: the same iterates, to round-off.
    const auto [diff, umax] = test::max_diff(a.U[0], b.U[0], d.local(), MPI_COMM_WORLD);
    EXPECT_GT(umax, 0.0);
    EXPECT_LE(diff, 1e-14 * umax);
    double fdiff = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        for (int c = 0; c < 3; ++c) fdiff = std::max(fdiff, std::abs(a.flux[0](i, j, k, c) - b.flux[0](i, j, k, c)));
    });
    EXPECT_LE(test::global_max(fdiff, MPI_COMM_WORLD), 1e-14 * 4.0 * std::numbers::pi * umax / kH);
}

}  // namespace
}  // namespace nimbus
