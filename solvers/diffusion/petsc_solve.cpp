// PETSc back end of the diffusion model (linear_solve.h): a cross-check of the hypre path
// through an independent stack. DMDA over the whole domain with the decomposition's slab
// ownership, AIJ matrix (or what -diffusion_dm_mat_type selects), KSP CG with PCHYPRE
// BoomerAMG, stopping on the unpreconditioned 2-norm ||r|| <= tol ||b||. PETSc options with
// the prefix "diffusion_" override these choices, from model.diffusion.petsc_options (a private
// options database) or else PETSc's global options (PETSC_OPTIONS). Geometric multigrid:
// "-diffusion_pc_type mg -diffusion_pc_mg_levels L -diffusion_pc_mg_galerkin both" coarsens
// the DMDA attached to the KSP, which PETSc allows only when n - 1 is divisible by 2^(L-1)
// along every axis (e.g. 49 cells, L = 3); otherwise KSPSetUp fails with PETSc's message.
#include <petscdmda.h>
#include <petscksp.h>

#include <cmath>
#include <optional>

#include <fmt/format.h>

#include "solvers/diffusion/linear_solve.h"
#include "solvers/diffusion/petsc_support.h"
#include "src/core/error.h"

namespace nimbus::diffusion {
namespace {

void check(PetscErrorCode ierr, const char* what) { petsc::check(ierr, "diffusion (petsc)", what); }

void ensure_petsc(MPI_Comm comm) { petsc::ensure_initialized(comm); }

// The DMDA's owning handle (the others: petsc_support.h), destroyed in reverse order of declaration.
struct DMHandle {
    DM dm = nullptr;
    ~DMHandle() { if (dm) DMDestroy(&dm); }
};
using petsc::KSPHandle;
using petsc::MatHandle;
using petsc::OptionsHandle;
using petsc::VecHandle;

}  // namespace

LinearSolveOutput solve_with_petsc(const Decomposition& d, const Assembler& assembler,
                                   const DiffusionProblem& p, const SolveRegion& region,
                                   const DiffusionOptions& opt, Report& report) {
    const MPI_Comm comm = d.comm();
    if (!d.is_slab_z())
        throw Error("diffusion: solver = petsc needs slabs along z (process grid 1 x 1 x P)");
    ensure_petsc(comm);
    LinearSolveOutput out;
    out.box = d.local().intersect(region.box);
    const Box& own = d.local();
    const size_t nrhs = p.Q0.size();

    double t0 = wall_time();
    std::optional<ScopedTimer> timer(std::in_place, report, "assemble");
    std::vector<PetscInt> lz(static_cast<size_t>(d.size()));
    for (int r = 0; r < d.size(); ++r) lz[static_cast<size_t>(r)] = d.box_of(r).size(2);
    DMBoundaryType bt[3];
    for (int a = 0; a < 3; ++a)
        bt[a] = (p.periodic[a] && p.n[a] > 1) ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_NONE;
    // model.diffusion.petsc_options: a private options database for this solve's DM and KSP
    // (declared first, so destroyed after them).
    OptionsHandle options;
    if (!opt.petsc_options.empty()) {
        check(PetscOptionsCreate(&options.o), "PetscOptionsCreate");
        check(PetscOptionsInsertString(options.o, opt.petsc_options.c_str()), "PetscOptionsInsertString (petsc_options)");
    }
    DMHandle da;
    check(DMDACreate3d(comm, bt[0], bt[1], bt[2], DMDA_STENCIL_STAR, p.n[0], p.n[1], p.n[2], 1, 1,
                       d.size(), 1, 1, nullptr, nullptr, lz.data(), &da.dm), "DMDACreate3d");
    if (options.o) check(PetscObjectSetOptions(reinterpret_cast<PetscObject>(da.dm), options.o), "PetscObjectSetOptions");
    check(DMSetOptionsPrefix(da.dm, "diffusion_"), "DMSetOptionsPrefix");
    check(DMSetFromOptions(da.dm), "DMSetFromOptions");
    check(DMSetUp(da.dm), "DMSetUp");
    PetscInt xs, ys, zs, xm, ym, zm;
    check(DMDAGetCorners(da.dm, &xs, &ys, &zs, &xm, &ym, &zm), "DMDAGetCorners");
    check_collective(comm, xs == own.lo[0] && ys == own.lo[1] && zs == own.lo[2] && xm == own.size(0) &&
                               ym == own.size(1) && zm == own.size(2),
                     "diffusion (petsc): DMDA ownership differs from the decomposition");

    MatHandle A;
    check(DMCreateMatrix(da.dm, &A.m), "DMCreateMatrix");
    const int offs[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for_each_cell(own, [&](int i, int j, int k) {
        MatStencil row{k, j, i, 0}, cols[7];
        PetscScalar vals[7];
        int n = 0;
        const bool in_region = region.box.contains(i, j, k);
        const CellRow cr = in_region ? assembler.row(i, j, k) : CellRow{};
        cols[n] = row;
        vals[n++] = cr.diag;
        for (int e = 0; e < 6; ++e) {
            if (cr.coupling[static_cast<size_t>(e)] == 0.0) continue;
            cols[n] = MatStencil{k + offs[e][2], j + offs[e][1], i + offs[e][0], 0};
            vals[n++] = -cr.coupling[static_cast<size_t>(e)];
        }
        check(MatSetValuesStencil(A.m, 1, &row, n, cols, vals, ADD_VALUES), "MatSetValuesStencil");
    });
    check(MatAssemblyBegin(A.m, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin");
    check(MatAssemblyEnd(A.m, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd");
    VecHandle b, x, res;
    check(DMCreateGlobalVector(da.dm, &b.v), "DMCreateGlobalVector");
    check(VecDuplicate(b.v, &x.v), "VecDuplicate");
    check(VecDuplicate(b.v, &res.v), "VecDuplicate");
    timer.reset();
    const double assemble_s = wall_time() - t0;

    t0 = wall_time();
    timer.emplace(report, "setup");
    KSPHandle ksp;
    check(KSPCreate(comm, &ksp.ksp), "KSPCreate");
    if (options.o) check(PetscObjectSetOptions(reinterpret_cast<PetscObject>(ksp.ksp), options.o), "PetscObjectSetOptions");
    check(KSPSetOptionsPrefix(ksp.ksp, "diffusion_"), "KSPSetOptionsPrefix");
    check(KSPSetOperators(ksp.ksp, A.m, A.m), "KSPSetOperators");
    // The DMDA rides along (inactive: the operator and right-hand sides are ours) so that
    // geometric preconditioners can coarsen it, e.g. -diffusion_pc_type mg with levels.
    check(KSPSetDM(ksp.ksp, da.dm), "KSPSetDM");
    check(KSPSetDMActive(ksp.ksp, PETSC_FALSE), "KSPSetDMActive");
    check(KSPSetType(ksp.ksp, KSPCG), "KSPSetType");
    PC pc;
    check(KSPGetPC(ksp.ksp, &pc), "KSPGetPC");
    check(PCSetType(pc, PCHYPRE), "PCSetType");
    check(PCHYPRESetType(pc, "boomeramg"), "PCHYPRESetType");
    check(KSPSetNormType(ksp.ksp, KSP_NORM_UNPRECONDITIONED), "KSPSetNormType");
    check(KSPSetTolerances(ksp.ksp, opt.tolerance, 0.0, PETSC_DEFAULT, opt.max_iterations),
          "KSPSetTolerances");
    check(KSPSetResidualHistory(ksp.ksp, nullptr, PETSC_DECIDE, PETSC_TRUE), "KSPSetResidualHistory");
    check(KSPSetFromOptions(ksp.ksp), "KSPSetFromOptions");
    check(KSPSetUp(ksp.ksp), "KSPSetUp");
    timer.reset();
    const double setup_s = wall_time() - t0;

    out.x.resize(nrhs);
    out.stats.resize(nrhs);
    for (size_t r = 0; r < nrhs; ++r) {
        SolveStats& st = out.stats[r];
        st.assemble_seconds = r == 0 ? assemble_s : 0.0;
        st.setup_seconds = r == 0 ? setup_s : 0.0;
        t0 = wall_time();
        timer.emplace(report, "solve");
        PetscScalar*** bv;
        check(DMDAVecGetArray(da.dm, b.v, &bv), "DMDAVecGetArray");
        for_each_cell(own, [&](int i, int j, int k) {
            bv[k][j][i] = region.box.contains(i, j, k) ? assembler.rhs(static_cast<int>(r), i, j, k) : 0.0;
        });
        check(DMDAVecRestoreArray(da.dm, b.v, &bv), "DMDAVecRestoreArray");
        PetscReal b_norm = 0, r_norm = 0;
        check(VecNorm(b.v, NORM_2, &b_norm), "VecNorm");
        check(VecSet(x.v, 0.0), "VecSet");
        if (b_norm > 0) {
            check(KSPSolve(ksp.ksp, b.v, x.v), "KSPSolve");
            PetscInt its = 0;
            check(KSPGetIterationNumber(ksp.ksp, &its), "KSPGetIterationNumber");
            PetscReal rn = 0;
            check(KSPGetResidualNorm(ksp.ksp, &rn), "KSPGetResidualNorm");
            st.iterations = static_cast<int>(its);
            st.reported_residual = rn / b_norm;
            check(MatMult(A.m, x.v, res.v), "MatMult");
            check(VecAYPX(res.v, -1.0, b.v), "VecAYPX");
            check(VecNorm(res.v, NORM_2, &r_norm), "VecNorm");
            st.true_residual = r_norm / b_norm;
        }
        timer.reset();
        st.solve_seconds = wall_time() - t0;
        if (!(st.true_residual <= opt.tolerance)) {
            const PetscReal* hist = nullptr;
            PetscInt nh = 0;
            KSPGetResidualHistory(ksp.ksp, &hist, &nh);
            std::vector<std::pair<int, double>> history;
            for (PetscInt h = 0; h < nh; ++h) history.emplace_back(static_cast<int>(h), hist[h] / b_norm);
            throw Error(fmt::format(
                "diffusion: petsc CG did not reach the relative residual {:.1e} in {} iterations "
                "(true residual {:.3e}); history, iteration: relative residual: {}",
                opt.tolerance, st.iterations, st.true_residual, format_history(history)));
        }
        const PetscScalar*** xv;
        check(DMDAVecGetArrayRead(da.dm, x.v, &xv), "DMDAVecGetArrayRead");
        out.x[r].clear();
        out.x[r].reserve(static_cast<size_t>(out.box.cells()));
        for_each_cell(out.box, [&](int i, int j, int k) { out.x[r].push_back(xv[k][j][i]); });
        check(DMDAVecRestoreArrayRead(da.dm, x.v, &xv), "DMDAVecRestoreArrayRead");
    }
    return out;
}

}  // namespace nimbus::diffusion
