#include "solvers/diffusion/hypre_struct.h"

#include <HYPRE_utilities.h>

#include "src/core/error.h"

namespace nimbus::diffusion::hypre {
namespace {

// hypre boxes are inclusive.
void to_hypre(const Box& b, HYPRE_Int lo[3], HYPRE_Int hi[3]) {
    for (int d = 0; d < 3; ++d) {
        lo[d] = b.lo[d];
        hi[d] = b.hi[d] - 1;
    }
}

// Preconditioner settings: one V-cycle, zero initial guess, symmetric smoothing.
void configure_pfmg(HYPRE_StructSolver s, bool as_precond, bool periodic) {
    // Galerkin coarse operators are requested, but only the Jacobi smoother gets them: with
    // red/black (types 2, 3) hypre's PFMGSetup switches to the non-Galerkin 7-point ParFlow
    // operator. On the noisy cumulus that operator over-corrects modes on small clusters of
    // capped edge cells: the largest eigenvalue of (V-cycle)·A is 1.10, 1.42, 1.83 at 64, 128,
    // 256³ (smallest 0.78, 0.75, 0.73), hence PFMG-PCG 8, 10, 12 iterations (README "Solvers").
    HYPRE_StructPFMGSetRAPType(s, 0);
    // As a preconditioner: red/black Gauss-Seidel in symmetric sweep order (type 2), except
    // on periodic grids where it broke PCG (no convergence in 200 iterations on a 4x4
    // periodic slab). Stand-alone: weighted Jacobi; red/black diverged (NaN) on a cloud.
    HYPRE_StructPFMGSetRelaxType(s, (as_precond && !periodic) ? 2 : 1);
    // Two pre- and two post-sweeps on EVERY level (skip_relax = 0; hypre's default skips
    // relaxation on some levels, which assumes a near-constant coefficient). On the cumulus
    // (coefficient contrast ~1e3, near-empty cells at the edge) this took PFMG-PCG from 26 to
    // 10 iterations at 128³ and halved the solve time (jobs/bench_diffusion.sh, README).
    HYPRE_StructPFMGSetNumPreRelax(s, 2);
    HYPRE_StructPFMGSetNumPostRelax(s, 2);
    HYPRE_StructPFMGSetSkipRelax(s, 0);
    HYPRE_StructPFMGSetRelChange(s, 0);
    if (as_precond) {
        HYPRE_StructPFMGSetMaxIter(s, 1);
        HYPRE_StructPFMGSetTol(s, 0.0);
        HYPRE_StructPFMGSetZeroGuess(s);
    } else {
        HYPRE_StructPFMGSetLogging(s, 1);
    }
}

void configure_smg(HYPRE_StructSolver s, bool as_precond) {
    HYPRE_StructSMGSetMemoryUse(s, 0);
    HYPRE_StructSMGSetNumPreRelax(s, 1);
    HYPRE_StructSMGSetNumPostRelax(s, 1);
    HYPRE_StructSMGSetRelChange(s, 0);
    if (as_precond) {
        HYPRE_StructSMGSetMaxIter(s, 1);
        HYPRE_StructSMGSetTol(s, 0.0);
        HYPRE_StructSMGSetZeroGuess(s);
    } else {
        HYPRE_StructSMGSetLogging(s, 1);
    }
}

}  // namespace

void ensure_initialized() {
    static bool done = false;
    if (!done) {
        HYPRE_Init();
        done = true;
    }
}

Grid::Grid(MPI_Comm comm, const Box& box, const Int3& period) {
    ensure_initialized();
    HYPRE_StructGridCreate(comm, 3, &g_);
    if (!box.empty()) {
        HYPRE_Int lo[3], hi[3];
        to_hypre(box, lo, hi);
        HYPRE_StructGridSetExtents(g_, lo, hi);
    }
    HYPRE_Int per[3] = {period[0], period[1], period[2]};
    if (per[0] > 0 || per[1] > 0 || per[2] > 0) HYPRE_StructGridSetPeriodic(g_, per);
    HYPRE_StructGridAssemble(g_);
}
Grid::~Grid() { HYPRE_StructGridDestroy(g_); }

SymmetricStencil7::SymmetricStencil7() {
    HYPRE_StructStencilCreate(3, kEntries, &s_);
    HYPRE_Int offsets[kEntries][3] = {{0, 0, 0}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
    for (int e = 0; e < kEntries; ++e) HYPRE_StructStencilSetElement(s_, e, offsets[e]);
}
SymmetricStencil7::~SymmetricStencil7() { HYPRE_StructStencilDestroy(s_); }

Matrix::Matrix(MPI_Comm comm, const Grid& grid, const SymmetricStencil7& stencil) {
    HYPRE_StructMatrixCreate(comm, grid.get(), stencil.get(), &A_);
    HYPRE_StructMatrixSetSymmetric(A_, 1);
    HYPRE_StructMatrixInitialize(A_);
}
Matrix::~Matrix() { HYPRE_StructMatrixDestroy(A_); }

void Matrix::set_box_values(const Box& box, std::vector<double>& values) {
    if (box.empty()) return;
    HYPRE_Int lo[3], hi[3];
    to_hypre(box, lo, hi);
    HYPRE_Int entries[SymmetricStencil7::kEntries] = {0, 1, 2, 3};
    HYPRE_StructMatrixSetBoxValues(A_, lo, hi, SymmetricStencil7::kEntries, entries, values.data());
}
void Matrix::assemble() { HYPRE_StructMatrixAssemble(A_); }

Vector::Vector(MPI_Comm comm, const Grid& grid) {
    HYPRE_StructVectorCreate(comm, grid.get(), &v_);
    HYPRE_StructVectorInitialize(v_);
    HYPRE_StructVectorSetConstantValues(v_, 0.0);
}
Vector::~Vector() { HYPRE_StructVectorDestroy(v_); }

void Vector::set_box_values(const Box& box, std::vector<double>& values) {
    if (box.empty()) return;
    HYPRE_Int lo[3], hi[3];
    to_hypre(box, lo, hi);
    HYPRE_StructVectorSetBoxValues(v_, lo, hi, values.data());
}
void Vector::get_box_values(const Box& box, std::vector<double>& values) const {
    values.assign(static_cast<size_t>(box.cells()), 0.0);
    if (box.empty()) return;
    HYPRE_Int lo[3], hi[3];
    to_hypre(box, lo, hi);
    HYPRE_StructVectorGetBoxValues(v_, lo, hi, values.data());
}
void Vector::assemble() { HYPRE_StructVectorAssemble(v_); }

void matvec(double alpha, const Matrix& A, const Vector& x, double beta, Vector& y) {
    HYPRE_StructMatrixMatvec(alpha, A.get(), x.get(), beta, y.get());
}

Solver::Solver(MPI_Comm comm, const std::string& kind, bool periodic) : kind_(kind) {
    pcg_ = kind == "pfmg-pcg" || kind == "smg-pcg";
    pfmg_ = kind == "pfmg" || kind == "pfmg-pcg";
    if (!pcg_ && kind != "pfmg" && kind != "smg")
        throw Error("diffusion: unknown hypre solver '" + kind + "'");
    HYPRE_StructSolver& mg = pcg_ ? precond_ : solver_;
    if (pfmg_) {
        HYPRE_StructPFMGCreate(comm, &mg);
        configure_pfmg(mg, pcg_, periodic);
    } else {
        HYPRE_StructSMGCreate(comm, &mg);
        configure_smg(mg, pcg_);
    }
    if (pcg_) {
        HYPRE_StructPCGCreate(comm, &solver_);
        HYPRE_StructPCGSetTwoNorm(solver_, 1);
        HYPRE_StructPCGSetRelChange(solver_, 0);
        HYPRE_StructPCGSetLogging(solver_, 1);
        if (pfmg_)
            HYPRE_StructPCGSetPrecond(solver_, HYPRE_StructPFMGSolve, HYPRE_StructPFMGSetup, precond_);
        else
            HYPRE_StructPCGSetPrecond(solver_, HYPRE_StructSMGSolve, HYPRE_StructSMGSetup, precond_);
    }
}

Solver::~Solver() {
    if (pcg_) HYPRE_StructPCGDestroy(solver_);
    HYPRE_StructSolver mg = pcg_ ? precond_ : solver_;
    if (pfmg_) HYPRE_StructPFMGDestroy(mg); else HYPRE_StructSMGDestroy(mg);
}

void Solver::set_tolerance(double tol) {
    if (pcg_) HYPRE_StructPCGSetTol(solver_, tol);
    else if (pfmg_) HYPRE_StructPFMGSetTol(solver_, tol);
    else HYPRE_StructSMGSetTol(solver_, tol);
}

void Solver::set_max_iterations(int n) {
    if (pcg_) HYPRE_StructPCGSetMaxIter(solver_, n);
    else if (pfmg_) HYPRE_StructPFMGSetMaxIter(solver_, n);
    else HYPRE_StructSMGSetMaxIter(solver_, n);
}

void Solver::setup(const Matrix& A, const Vector& b, Vector& x) {
    if (pcg_) HYPRE_StructPCGSetup(solver_, A.get(), b.get(), x.get());
    else if (pfmg_) HYPRE_StructPFMGSetup(solver_, A.get(), b.get(), x.get());
    else HYPRE_StructSMGSetup(solver_, A.get(), b.get(), x.get());
}

void Solver::solve(const Matrix& A, const Vector& b, Vector& x) {
    if (pcg_) HYPRE_StructPCGSolve(solver_, A.get(), b.get(), x.get());
    else if (pfmg_) HYPRE_StructPFMGSolve(solver_, A.get(), b.get(), x.get());
    else HYPRE_StructSMGSolve(solver_, A.get(), b.get(), x.get());
    HYPRE_ClearAllErrors();  // non-convergence is judged by the caller on the true residual
}

int Solver::iterations() const {
    HYPRE_Int n = 0;
    if (pcg_) HYPRE_StructPCGGetNumIterations(solver_, &n);
    else if (pfmg_) HYPRE_StructPFMGGetNumIterations(solver_, &n);
    else HYPRE_StructSMGGetNumIterations(solver_, &n);
    return static_cast<int>(n);
}

double Solver::final_relative_residual() const {
    HYPRE_Real r = 0;
    if (pcg_) HYPRE_StructPCGGetFinalRelativeResidualNorm(solver_, &r);
    else if (pfmg_) HYPRE_StructPFMGGetFinalRelativeResidualNorm(solver_, &r);
    else HYPRE_StructSMGGetFinalRelativeResidualNorm(solver_, &r);
    return static_cast<double>(r);
}

}  // namespace nimbus::diffusion::hypre

