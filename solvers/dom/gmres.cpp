#include "solvers/dom/gmres.h"

#include <petscksp.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include "solvers/diffusion/petsc_support.h"
#include "solvers/dom/dsa.h"
#include "src/core/error.h"
#include "src/physics/angular_moments.h"

namespace nimbus::dom {
namespace {

void check(PetscErrorCode ierr, const char* what) { petsc::check(ierr, "dom (gmres)", what); }

void ensure_petsc(MPI_Comm comm) { petsc::ensure_initialized(comm); }

// What MatMult needs; owned by gmres_band's frame.
struct ShellContext {
    TransportSweeper* sweeper;
    const BandProblem* p;
    std::vector<double> chi;  // per moment
    std::vector<double> s;    // source moments, packed on the source rows like the Krylov vectors
    SweepSource scatter_only; // no lights
    SweepOutput out;
    int sweeps = 0;
    std::string failure;  // a sweep's error (collective: every rank fails together), rethrown after
};

// y = x - K x. An error must not unwind through PETSc's C frames: a failed sweep is recorded,
// y = x returned, and the convergence test stops the solve (as dsa_apply does).
PetscErrorCode shell_mult(Mat A, Vec x, Vec y) {
    ShellContext* c = nullptr;
    PetscCall(MatShellGetContext(A, &c));
    const PetscScalar* xv = nullptr;
    PetscCall(VecGetArrayRead(x, &xv));
    make_source_moments(*c->p, c->chi, *c->scatter_only.rows, xv, c->s.data(), false);
    if (!c->failure.empty()) {
        PetscCall(VecRestoreArrayRead(x, &xv));
        PetscCall(VecCopy(x, y));
        return 0;
    }
    try {
        c->sweeper->sweep(c->scatter_only, c->out);
    } catch (const Error& e) {
        c->failure = e.what();
        PetscCall(VecRestoreArrayRead(x, &xv));
        PetscCall(VecCopy(x, y));
        return 0;
    }
    ++c->sweeps;
    PetscScalar* yv = nullptr;
    PetscCall(VecGetArray(y, &yv));
    const double* phi = c->out.phi.data();  // packed as x
    for (size_t q = 0; q < c->out.phi.size(); ++q) yv[q] = xv[q] - phi[q];
    PetscCall(VecRestoreArray(y, &yv));
    PetscCall(VecRestoreArrayRead(x, &xv));
    return 0;
}

// What the preconditioner and the convergence test need; owned by gmres_band's frame.
struct KrylovContext {
    const SourceRows* rows = nullptr;  // the cells of the Krylov vectors
    int nmom = 0;
    DiffusionSynthetic* dsa = nullptr;  // null: no preconditioner
    Report* report = nullptr;
    const std::string* sweep_failure = nullptr;  // ShellContext::failure
    Field<double> r0, r1;               // fluence and flux change handed to the DSA solve
    int dsa_iterations = 0;
    std::string failure;  // a DSA solve's error: reported by the convergence test, rethrown after
    double tolerance = 0;
    PetscInt max_iterations = 0;
    Vec work = nullptr;
    PetscInt last_recorded = 0;
    std::vector<double> history;  // ||P^{-1} r_k|| / ||phi_k||, k = 1, 2, ...
    const IterationMonitor* monitor = nullptr;  // told of each new history entry
};

// y = P^{-1} x = x + e_0 δ + e_1 δF, the DSA corrections (dsa.h) of the fluence change
// R0 = sqrt(4π) x_0 and the flux change R1 = sqrt(4π/3) (x_3, x_1, x_2) (Y_00 = 1/sqrt(4π),
// first_moment_axis and first_moment_scale in angular_moments.h); the corrections return to the
// moments times Y.
PetscErrorCode dsa_apply(PC pc, Vec x, Vec y) {
    KrylovContext* c = nullptr;
    PetscCall(PCShellGetContext(pc, &c));
    PetscCall(VecCopy(x, y));
    if (!c->failure.empty()) return 0;
    const double sqrt4pi = std::sqrt(4.0 * std::acos(-1.0)), y1 = first_moment_scale();
    const size_t nmom = static_cast<size_t>(c->nmom);
    const bool first_moments = nmom >= 4;
    const PetscScalar* xv = nullptr;
    PetscCall(VecGetArrayRead(x, &xv));
    double* r0 = c->r0.data();  // 0 outside the source rows (never written there)
    double* r1 = c->r1.data();
    c->rows->for_each_cell([&](size_t cell, size_t q) {
        r0[cell] = sqrt4pi * xv[q * nmom];
        if (!first_moments) return;
        for (int m = 1; m <= 3; ++m) r1[3 * cell + first_moment_axis(m)] = xv[q * nmom + m] / y1;
    });
    PetscCall(VecRestoreArrayRead(x, &xv));
    try {
        ScopedTimer t(*c->report, "dsa_solve");
        c->dsa_iterations += c->dsa->solve(c->r0, first_moments ? &c->r1 : nullptr);
    } catch (const Error& e) {  // collective: every rank fails together (dsa.h)
        c->failure = e.what();
        return 0;
    }
    const double* delta = c->dsa->last_correction().data();
    const Field<double>& current = c->dsa->last_current_correction();
    const double* dF = current.data();
    PetscScalar* yv = nullptr;
    PetscCall(VecGetArray(y, &yv));
    // The corrections return to the cells of the Krylov vectors, the source rows' (gmres_band).
    c->rows->for_each_cell([&](size_t cell, size_t q) {
        yv[q * nmom] += delta[cell] / sqrt4pi;
        if (!first_moments) return;
        for (int m = 1; m <= 3; ++m) yv[q * nmom + m] += y1 * dF[3 * cell + first_moment_axis(m)];
    });
    PetscCall(VecRestoreArray(y, &yv));
    return 0;
}

// Converged when ||P^{-1} r_k||_2 <= tolerance ||phi_k||_2 (gmres.h); rnorm is the
// preconditioned residual norm (left preconditioning, KSP_NORM_PRECONDITIONED).
PetscErrorCode converged_test(KSP ksp, PetscInt it, PetscReal rnorm, KSPConvergedReason* reason, void* ctx) {
    auto* c = static_cast<KrylovContext*>(ctx);
    *reason = KSP_CONVERGED_ITERATING;
    if (!c->failure.empty() || !c->sweep_failure->empty()) {
        *reason = KSP_DIVERGED_PC_FAILED;
        return 0;
    }
    if (!std::isfinite(rnorm)) {
        *reason = KSP_DIVERGED_NANORINF;
        return 0;
    }
    Vec phi = nullptr;
    PetscCall(KSPBuildSolution(ksp, c->work, &phi));
    PetscReal phi_norm = 0;
    PetscCall(VecNorm(phi, NORM_2, &phi_norm));
    const double rel = rnorm == 0 ? 0.0 : phi_norm > 0 ? rnorm / phi_norm : std::numeric_limits<double>::infinity();
    if (it > c->last_recorded) {  // a restart calls the test again with the same it
        c->history.push_back(rel);
        c->last_recorded = it;
        if (c->monitor) notify(*c->monitor, c->history);
    }
    if (rel <= c->tolerance)
        *reason = KSP_CONVERGED_RTOL;
    else if (it >= c->max_iterations)
        *reason = KSP_DIVERGED_ITS;
    return 0;
}

}  // namespace

IterationResult gmres_band(const Decomposition& d, TransportSweeper& sweeper, const AngularSet& ang,
                           const BandProblem& p, double tolerance, int max_iterations, SweepOutput& out,
                           Report& report, GmresPreconditioner preconditioner, const IterationMonitor& monitor) {
    const double t0 = MPI_Wtime();
    const MPI_Comm comm = d.comm();
    ensure_petsc(comm);
    const petsc::QuietErrors quiet;  // errors: one Error, no traceback (petsc_support.h)
    IterationResult res;
    const Box& own = d.local();
    const int nmom = ang.nmom;
    const size_t nm = static_cast<size_t>(nmom);
    // The Krylov vectors hold the moments of the source rows' cells only, packed (transport_sweep.h):
    // elsewhere sigma_s is 0, so moments there would feed no source, and the sweep stores none.
    const SourceRows rows = source_rows(p);
    std::int64_t unknowns[2] = {static_cast<std::int64_t>(rows.cells() * nm), 0};  // this rank's, all ranks'
    MPI_Allreduce(&unknowns[0], &unknowns[1], 1, MPI_INT64_T, MPI_SUM, comm);
    check_collective(comm, unknowns[1] <= PETSC_MAX_INT,
                     fmt::format("dom: gmres: the Krylov vectors would hold {} moments (cells that scatter x {} "
                                 "moments), more than this PETSc build's integers hold ({}): use iteration = "
                                 "\"dsa\", a lower legendre_order or a coarser grid, or a PETSc configured with "
                                 "--with-64-bit-indices",
                                 unknowns[1], nmom, static_cast<std::int64_t>(PETSC_MAX_INT)));
    const PetscInt nloc = static_cast<PetscInt>(unknowns[0]);
    ShellContext c{&sweeper, &p, moment_chi(p, ang), std::vector<double>(rows.cells() * nm, 0.0), {}, {}, 0, {}};
    c.scatter_only.kappa = &p.kappa;
    c.scatter_only.moments = c.s;
    c.scatter_only.nl = 0;
    c.scatter_only.rows = &rows;
    // Every sweep but the last covers the bounding box of the medium and its sources
    // (TransportSweeper::region).
    const std::optional<Box> region = sweeper.region(p.kappa, rows);
    c.scatter_only.region = region ? &*region : nullptr;

    // b: one sweep of the external source (lights + emission), scattering off.
    SweepSource external;
    external.kappa = &p.kappa;
    external.moments = c.s;
    external.amp = &p.amp;
    external.nl = p.nl;
    external.light_phase = p.light_phase;
    external.rows = &rows;
    external.region = c.scatter_only.region;
    const double y0inv = std::sqrt(4.0 * std::acos(-1.0));
    rows.for_each_cell([&](size_t cell, size_t q) { c.s[q * nm] = y0inv * p.emission.data()[cell]; });
    sweeper.sweep(external, out);

    // Owning handles (petsc_support.h): nothing leaks when a check or the DSA set-up throws.
    petsc::VecHandle bh, xh, work;
    petsc::MatHandle Ah;
    petsc::KSPHandle kh;
    check(VecCreateMPI(comm, nloc, PETSC_DETERMINE, &bh.v), "VecCreateMPI");
    check(VecDuplicate(bh.v, &xh.v), "VecDuplicate");
    const Vec b = bh.v, x = xh.v;
    {
        PetscScalar* bv = nullptr;
        check(VecGetArray(b, &bv), "VecGetArray");
        std::copy(out.phi.begin(), out.phi.end(), bv);  // packed as the Krylov vectors
        check(VecRestoreArray(b, &bv), "VecRestoreArray");
    }
    check(MatCreateShell(comm, nloc, nloc, PETSC_DETERMINE, PETSC_DETERMINE, &c, &Ah.m), "MatCreateShell");
    const Mat A = Ah.m;
    check(MatShellSetOperation(A, MATOP_MULT, reinterpret_cast<void (*)(void)>(shell_mult)), "MatShellSetOperation");
    check(KSPCreate(comm, &kh.ksp), "KSPCreate");
    const KSP ksp = kh.ksp;
    check(KSPSetOperators(ksp, A, A), "KSPSetOperators");
    check(KSPSetType(ksp, KSPGMRES), "KSPSetType");
    check(KSPGMRESSetRestart(ksp, 30), "KSPGMRESSetRestart");
    KrylovContext kc;
    kc.sweep_failure = &c.failure;
    kc.rows = &rows;
    kc.nmom = nmom;
    kc.report = &report;
    kc.tolerance = tolerance;
    kc.max_iterations = max_iterations;
    kc.monitor = &monitor;
    std::unique_ptr<DiffusionSynthetic> dsa;
    if (preconditioner == GmresPreconditioner::dsa) {
        ScopedTimer t(report, "dsa_setup");
        // DiffusionSynthetic::kVCycles PFMG V-cycles per application (gmres.h): a fixed linear map.
        dsa = std::make_unique<DiffusionSynthetic>(d, p, sweeper.boundary().reflective);
        kc.dsa = dsa.get();
        kc.r0 = Field<double>(own, 0, 1, 0.0);
        kc.r1 = Field<double>(own, 0, 3, 0.0);
    }
    PC pc = nullptr;
    check(KSPGetPC(ksp, &pc), "KSPGetPC");
    if (kc.dsa) {
        check(PCSetType(pc, PCSHELL), "PCSetType");
        check(PCShellSetContext(pc, &kc), "PCShellSetContext");
        check(PCShellSetApply(pc, dsa_apply), "PCShellSetApply");
        check(PCShellSetName(pc, "dom DSA"), "PCShellSetName");
    } else {
        check(PCSetType(pc, PCNONE), "PCSetType");
    }
    check(KSPSetPCSide(ksp, PC_LEFT), "KSPSetPCSide");
    check(KSPSetNormType(ksp, KSP_NORM_PRECONDITIONED), "KSPSetNormType");
    check(KSPSetTolerances(ksp, tolerance, 0.0, 1e300, max_iterations), "KSPSetTolerances");
    check(VecDuplicate(b, &work.v), "VecDuplicate");
    kc.work = work.v;
    check(KSPSetConvergenceTest(ksp, converged_test, &kc, nullptr), "KSPSetConvergenceTest");
    // Initial guess 0: the first residual is b without a sweep (measured on the tau-100 cube:
    // the same 5 iterations as from phi = b, one sweep fewer).
    check(VecSet(x, 0.0), "VecSet");
    const PetscErrorCode solve_err = KSPSolve(ksp, b, x);
    KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
    PetscInt its = 0;
    KSPGetConvergedReason(ksp, &reason);
    KSPGetIterationNumber(ksp, &its);
    res.history = kc.history;
    res.iterations = static_cast<int>(its);
    res.converged = solve_err == 0 && reason > 0;
    res.dsa_linear_iterations = kc.dsa_iterations;
    if (!c.failure.empty()) throw Error(c.failure);
    if (!kc.failure.empty()) throw Error(kc.failure);
    check(solve_err, "KSPSolve");
    // Last sweep from the solution x: phi = K x + b, with fluence, flux and leakage.
    {
        const PetscScalar* xv = nullptr;
        check(VecGetArrayRead(x, &xv), "VecGetArrayRead");
        make_source_moments(p, c.chi, rows, xv, c.s.data(), true);
        check(VecRestoreArrayRead(x, &xv), "VecRestoreArrayRead");
    }
    external.region = nullptr;
    sweeper.sweep(external, out);
    res.seconds = MPI_Wtime() - t0;
    return res;
}

}  // namespace nimbus::dom
