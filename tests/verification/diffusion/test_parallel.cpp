// (d) Decomposition invariance: the model on the world communicator (slabs along z) and on
// MPI_COMM_SELF (each rank solves the whole domain) agree to the solver tolerance.
// (e) The PETSc path (KSP CG + BoomerAMG) and every hypre solver agree with PFMG-PCG.
#include <gtest/gtest.h>

#include "diffusion_test_util.h"
#include "solvers/diffusion/diffusion.h"
#include "src/scene/medium.h"
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

// With ||b - A x|| <= tol ||b||, two solutions differ by at most ~cond(A) tol; for this cloud
// the measured difference is ~1e-9 relative at tol = 1e-10, checked against 100 tol.
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

}  // namespace
}  // namespace nimbus
