#include "solvers/dom/gmres.h"

#include <petscksp.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "solvers/diffusion/petsc_support.h"
#include "src/core/error.h"

namespace nimbus::dom {
namespace {

void check(PetscErrorCode ierr, const char* what) { petsc::check(ierr, "dom (gmres)", what); }

void ensure_petsc(MPI_Comm comm) { petsc::ensure_initialized(comm); }

// What MatMult needs; owned by gmres_band's frame.
struct ShellContext {
    TransportSweeper* sweeper;
    const AngularSet* ang;
    const BandProblem* p;
    std::vector<double> chi;  // per moment
    Field<double> s;          // source moments
    SweepSource scatter_only; // no lights
    SweepOutput out;
    int sweeps = 0;
};

// y = x - K x.
PetscErrorCode shell_mult(Mat A, Vec x, Vec y) {
    ShellContext* c = nullptr;
    PetscCall(MatShellGetContext(A, &c));
    const PetscScalar* xv = nullptr;
    PetscCall(VecGetArrayRead(x, &xv));
    const int nmom = c->ang->nmom;
    const size_t ncell = static_cast<size_t>(c->p->kappa.owned().cells());
    const double* ss = c->p->sigma_s.data();
    double* s = c->s.data();
    for (size_t q = 0; q < ncell; ++q)
        for (int k = 0; k < nmom; ++k) s[q * nmom + k] = ss[q] * c->chi[static_cast<size_t>(k)] * xv[q * nmom + k];
    c->sweeper->sweep(c->scatter_only, c->out);
    ++c->sweeps;
    PetscScalar* yv = nullptr;
    PetscCall(VecGetArray(y, &yv));
    const double* phi = c->out.phi.data();
    for (size_t q = 0; q < ncell * static_cast<size_t>(nmom); ++q) yv[q] = xv[q] - phi[q];
    PetscCall(VecRestoreArray(y, &yv));
    PetscCall(VecRestoreArrayRead(x, &xv));
    return 0;
}

PetscErrorCode record_residual(KSP, PetscInt, PetscReal rnorm, void* ctx) {
    auto* h = static_cast<std::vector<double>*>(ctx);
    h->push_back(rnorm);
    return 0;
}

}  // namespace

IterationResult gmres_band(const Decomposition& d, TransportSweeper& sweeper, const AngularSet& ang,
                           const BandProblem& p, double tolerance, int max_iterations, SweepOutput& out,
                           Report& report) {
    (void)report;
    const double t0 = MPI_Wtime();
    const MPI_Comm comm = d.comm();
    ensure_petsc(comm);
    IterationResult res;
    const Box& own = d.local();
    const int nmom = ang.nmom;
    const PetscInt nloc = static_cast<PetscInt>(own.cells() * nmom);
    ShellContext c{&sweeper, &ang, &p, {}, Field<double>(own, 0, nmom, 0.0), {}, {}, 0};
    for (int k = 0; k < nmom; ++k) {
        const int l = ang.degree[static_cast<size_t>(k)];
        c.chi.push_back(l < static_cast<int>(p.phase.chi.size()) ? p.phase.chi[static_cast<size_t>(l)] : 0.0);
    }
    c.scatter_only.kappa = &p.kappa;
    c.scatter_only.moments = &c.s;
    c.scatter_only.nl = 0;

    // b: one sweep of the external source (lights + emission), scattering off.
    SweepSource external;
    external.kappa = &p.kappa;
    external.moments = &c.s;
    external.amp = &p.amp;
    external.nl = p.nl;
    external.light_phase = p.light_phase;
    const double y0inv = std::sqrt(4.0 * std::acos(-1.0));
    c.s.fill(0.0);
    for (std::ptrdiff_t q = 0; q < own.cells(); ++q) c.s.data()[q * nmom] = y0inv * p.emission.data()[q];
    sweeper.sweep(external, out);

    Vec b = nullptr, x = nullptr;
    Mat A = nullptr;
    KSP ksp = nullptr;
    check(VecCreateMPI(comm, nloc, PETSC_DETERMINE, &b), "VecCreateMPI");
    check(VecDuplicate(b, &x), "VecDuplicate");
    {
        PetscScalar* bv = nullptr;
        check(VecGetArray(b, &bv), "VecGetArray");
        std::copy(out.phi.data(), out.phi.data() + nloc, bv);
        check(VecRestoreArray(b, &bv), "VecRestoreArray");
    }
    check(MatCreateShell(comm, nloc, nloc, PETSC_DETERMINE, PETSC_DETERMINE, &c, &A), "MatCreateShell");
    check(MatShellSetOperation(A, MATOP_MULT, reinterpret_cast<void (*)(void)>(shell_mult)), "MatShellSetOperation");
    check(KSPCreate(comm, &ksp), "KSPCreate");
    check(KSPSetOperators(ksp, A, A), "KSPSetOperators");
    check(KSPSetType(ksp, KSPGMRES), "KSPSetType");
    check(KSPGMRESSetRestart(ksp, 30), "KSPGMRESSetRestart");
    PC pc = nullptr;
    check(KSPGetPC(ksp, &pc), "KSPGetPC");
    check(PCSetType(pc, PCNONE), "PCSetType");
    check(KSPSetNormType(ksp, KSP_NORM_UNPRECONDITIONED), "KSPSetNormType");
    check(KSPSetTolerances(ksp, tolerance, 0.0, 1e300, max_iterations), "KSPSetTolerances");
    std::vector<double> rnorm;
    check(KSPMonitorSet(ksp, record_residual, &rnorm, nullptr), "KSPMonitorSet");
    check(VecCopy(b, x), "VecCopy");  // initial guess: the first-collision moments
    check(KSPSetInitialGuessNonzero(ksp, PETSC_TRUE), "KSPSetInitialGuessNonzero");
    const PetscErrorCode solve_err = KSPSolve(ksp, b, x);
    KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
    PetscInt its = 0;
    KSPGetConvergedReason(ksp, &reason);
    KSPGetIterationNumber(ksp, &its);
    PetscReal bnorm = 0;
    VecNorm(b, NORM_2, &bnorm);
    for (double r : rnorm) res.history.push_back(bnorm > 0 ? r / bnorm : 0.0);
    res.iterations = static_cast<int>(its);
    res.converged = solve_err == 0 && reason > 0;
    // Last sweep from the solution: phi = K x + b, with fluence, flux and leakage.
    Field<double> phi(own, 0, nmom, 0.0);
    {
        const PetscScalar* xv = nullptr;
        VecGetArrayRead(x, &xv);
        std::copy(xv, xv + nloc, phi.data());
        VecRestoreArrayRead(x, &xv);
    }
    KSPDestroy(&ksp);
    MatDestroy(&A);
    VecDestroy(&x);
    VecDestroy(&b);
    check(solve_err, "KSPSolve");
    const size_t ncell = static_cast<size_t>(own.cells());
    for (size_t q = 0; q < ncell; ++q) {
        for (int k = 0; k < nmom; ++k)
            c.s.data()[q * nmom + k] = p.sigma_s.data()[q] * c.chi[static_cast<size_t>(k)] * phi.data()[q * nmom + k];
        c.s.data()[q * nmom] += y0inv * p.emission.data()[q];
    }
    sweeper.sweep(external, out);
    res.seconds = MPI_Wtime() - t0;
    return res;
}

}  // namespace nimbus::dom
