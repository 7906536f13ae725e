#include "solvers/diffusion/hypre_struct.h"

#include <HYPRE_utilities.h>
#include <cmath>
#include <cstdint>
#include <limits>
#include <fmt/format.h>

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

// hypre's calls return its global error flag, which stays set until cleared: a failure in a
// rank-local call (Create, Set...) shows in the return of that rank's next collective call.
// So the collective calls (Assemble, Initialize, Setup, Solve, Matvec, and the reads every rank
// makes after a solve) are checked, on every rank together; the rank-local ones are not. Every
// bit but HYPRE_ERROR_CONV is a failure (non-convergence is judged by the caller on the true
// residual, hypre_solve.cpp).
HYPRE_Int failure_bits(HYPRE_Int err) { return err & ~HYPRE_Int{HYPRE_ERROR_CONV}; }

std::string describe(HYPRE_Int err, const char* call) {
    char text[512] = {};
    HYPRE_DescribeError(err, text);
    return fmt::format("diffusion: hypre's {} failed (error {}: {})", call, err, text);
}

// A failure on any rank of comm is an Error on every rank.
void check_all(MPI_Comm comm, HYPRE_Int err, const char* call) {
    const bool ok = failure_bits(err) == 0;
    if (!ok) HYPRE_ClearAllErrors();
    check_collective(comm, ok, ok ? std::string() : describe(err, call));
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

// The calls of one hypre Struct solver, chosen once (Solver's constructor).
struct SolverCalls {
    const char* name;
    HYPRE_Int (*destroy)(HYPRE_StructSolver);
    HYPRE_Int (*set_tol)(HYPRE_StructSolver, HYPRE_Real);
    HYPRE_Int (*set_max_iter)(HYPRE_StructSolver, HYPRE_Int);
    HYPRE_PtrToStructSolverFcn setup, solve;
    HYPRE_Int (*iterations)(HYPRE_StructSolver, HYPRE_Int*);
    HYPRE_Int (*final_residual)(HYPRE_StructSolver, HYPRE_Real*);
};

namespace {
constexpr SolverCalls kPcg{"PCG", HYPRE_StructPCGDestroy, HYPRE_StructPCGSetTol, HYPRE_StructPCGSetMaxIter,
                           HYPRE_StructPCGSetup, HYPRE_StructPCGSolve, HYPRE_StructPCGGetNumIterations,
                           HYPRE_StructPCGGetFinalRelativeResidualNorm};
constexpr SolverCalls kPfmg{"PFMG", HYPRE_StructPFMGDestroy, HYPRE_StructPFMGSetTol, HYPRE_StructPFMGSetMaxIter,
                            HYPRE_StructPFMGSetup, HYPRE_StructPFMGSolve, HYPRE_StructPFMGGetNumIterations,
                            HYPRE_StructPFMGGetFinalRelativeResidualNorm};
constexpr SolverCalls kSmg{"SMG", HYPRE_StructSMGDestroy, HYPRE_StructSMGSetTol, HYPRE_StructSMGSetMaxIter,
                           HYPRE_StructSMGSetup, HYPRE_StructSMGSolve, HYPRE_StructSMGGetNumIterations,
                           HYPRE_StructSMGGetFinalRelativeResidualNorm};
}  // namespace

void ensure_initialized() {
    static bool done = false;
    if (!done) {
        HYPRE_Init();
        done = true;
    }
}

Grid::Grid(MPI_Comm comm, const Box& box, const Int3& period) {
    // hypre counts the grid's cells in HYPRE_BigInt, 32 bits unless hypre was configured with
    // --enable-bigint (Debian's is not): refuse what would wrap, before hypre sees it.
    std::int64_t cells = box.cells();
    MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPI_INT64_T, MPI_SUM, comm);
    check_collective(comm, cells <= std::numeric_limits<HYPRE_BigInt>::max(),
                     fmt::format("hypre: the structured system has {} cells, more than this hypre build's integers "
                                 "hold ({}): use a coarser grid, or a hypre configured with --enable-bigint",
                                 cells, std::numeric_limits<HYPRE_BigInt>::max()));
    ensure_initialized();
    HYPRE_StructGridCreate(comm, 3, &g_);
    if (!box.empty()) {
        HYPRE_Int lo[3], hi[3];
        to_hypre(box, lo, hi);
        HYPRE_StructGridSetExtents(g_, lo, hi);
    }
    HYPRE_Int per[3] = {period[0], period[1], period[2]};
    if (per[0] > 0 || per[1] > 0 || per[2] > 0) HYPRE_StructGridSetPeriodic(g_, per);
    try {
        check_all(comm, HYPRE_StructGridAssemble(g_), "StructGridAssemble");
    } catch (...) {  // the destructor does not run for a constructor that throws
        HYPRE_StructGridDestroy(g_);
        throw;
    }
}
Grid::~Grid() { HYPRE_StructGridDestroy(g_); }

SymmetricStencil7::SymmetricStencil7() {
    HYPRE_StructStencilCreate(3, kEntries, &s_);
    HYPRE_Int offsets[kEntries][3] = {{0, 0, 0}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
    for (int e = 0; e < kEntries; ++e) HYPRE_StructStencilSetElement(s_, e, offsets[e]);
}
SymmetricStencil7::~SymmetricStencil7() { HYPRE_StructStencilDestroy(s_); }

Matrix::Matrix(MPI_Comm comm, const Grid& grid, const SymmetricStencil7& stencil) : comm_(comm) {
    HYPRE_StructMatrixCreate(comm, grid.get(), stencil.get(), &A_);
    HYPRE_StructMatrixSetSymmetric(A_, 1);
    try {
        check_all(comm, HYPRE_StructMatrixInitialize(A_), "StructMatrixInitialize");
    } catch (...) {  // the destructor does not run for a constructor that throws
        HYPRE_StructMatrixDestroy(A_);
        throw;
    }
}
Matrix::~Matrix() { HYPRE_StructMatrixDestroy(A_); }

void Matrix::set_box_values(const Box& box, std::vector<double>& values) {
    if (box.empty()) return;
    HYPRE_Int lo[3], hi[3];
    to_hypre(box, lo, hi);
    HYPRE_Int entries[SymmetricStencil7::kEntries] = {0, 1, 2, 3};
    HYPRE_StructMatrixSetBoxValues(A_, lo, hi, SymmetricStencil7::kEntries, entries, values.data());
}
void Matrix::assemble() { check_all(comm_, HYPRE_StructMatrixAssemble(A_), "StructMatrixAssemble"); }

Vector::Vector(MPI_Comm comm, const Grid& grid) : comm_(comm) {
    HYPRE_StructVectorCreate(comm, grid.get(), &v_);
    try {
        check_all(comm, HYPRE_StructVectorInitialize(v_), "StructVectorInitialize");
    } catch (...) {  // the destructor does not run for a constructor that throws
        HYPRE_StructVectorDestroy(v_);
        throw;
    }
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
    HYPRE_Int err = 0;
    if (!box.empty()) {
        HYPRE_Int lo[3], hi[3];
        to_hypre(box, lo, hi);
        err = HYPRE_StructVectorGetBoxValues(v_, lo, hi, values.data());
    }
    check_all(comm_, err, "StructVectorGetBoxValues");
}
void Vector::assemble() { check_all(comm_, HYPRE_StructVectorAssemble(v_), "StructVectorAssemble"); }

void matvec(double alpha, const Matrix& A, const Vector& x, double beta, Vector& y) {
    check_all(A.comm(), HYPRE_StructMatrixMatvec(alpha, A.get(), x.get(), beta, y.get()), "StructMatrixMatvec");
}

Solver::Solver(MPI_Comm comm, const std::string& kind, bool periodic) : comm_(comm) {
    const bool pcg = kind == "pfmg-pcg" || kind == "smg-pcg";
    const bool cycle = kind == "pfmg-cycle";  // one V-cycle as PCG's preconditioner runs it
    const bool pfmg = kind == "pfmg" || kind == "pfmg-pcg" || cycle;
    if (!pcg && !pfmg && kind != "smg") throw Error("diffusion: unknown hypre solver '" + kind + "'");
    mg_calls_ = pfmg ? &kPfmg : &kSmg;
    calls_ = pcg ? &kPcg : mg_calls_;
    HYPRE_StructSolver& mg = pcg ? precond_ : solver_;
    if (pfmg) {
        HYPRE_StructPFMGCreate(comm, &mg);
        configure_pfmg(mg, pcg || cycle, periodic);
    } else {
        HYPRE_StructSMGCreate(comm, &mg);
        configure_smg(mg, pcg);
    }
    if (pcg) {
        HYPRE_StructPCGCreate(comm, &solver_);
        HYPRE_StructPCGSetTwoNorm(solver_, 1);
        HYPRE_StructPCGSetRelChange(solver_, 0);
        HYPRE_StructPCGSetLogging(solver_, 1);
        HYPRE_StructPCGSetPrecond(solver_, mg_calls_->solve, mg_calls_->setup, precond_);
    }
}

Solver::~Solver() {
    calls_->destroy(solver_);
    if (precond_) mg_calls_->destroy(precond_);
}

void Solver::set_tolerance(double tol) { calls_->set_tol(solver_, tol); }

void Solver::set_max_iterations(int n) { calls_->set_max_iter(solver_, n); }

void Solver::setup(const Matrix& A, const Vector& b, Vector& x) {
    check_all(comm_, calls_->setup(solver_, A.get(), b.get(), x.get()), "Setup");
}

void Solver::solve(const Matrix& A, const Vector& b, Vector& x) {
    // Only argument and memory errors fail here. Non-convergence and a breakdown (PCG's
    // generic error on a NaN) leave a residual that the caller checks on the true residual and
    // reports with its history (hypre_solve.cpp).
    const HYPRE_Int err = calls_->solve(solver_, A.get(), b.get(), x.get());
    HYPRE_ClearAllErrors();
    check_all(comm_, err & (HYPRE_ERROR_MEMORY | HYPRE_ERROR_ARG), calls_->name);
}

int Solver::iterations() const {
    HYPRE_Int n = 0;
    check_all(comm_, calls_->iterations(solver_, &n), "GetNumIterations");
    return static_cast<int>(n);
}

double Solver::final_relative_residual() const {
    HYPRE_Real r = 0;
    check_all(comm_, calls_->final_residual(solver_, &r), "GetFinalRelativeResidualNorm");
    return static_cast<double>(r);
}

double global_norm(const std::vector<double>& v, MPI_Comm comm) {
    double s = 0.0, g = 0.0;
    for (double a : v) s += a * a;
    MPI_Allreduce(&s, &g, 1, MPI_DOUBLE, MPI_SUM, comm);
    return std::sqrt(g);
}

double true_relative_residual(MPI_Comm comm, const Matrix& A, const Vector& x, std::vector<double>& b_values,
                              double b_norm, const Box& box, Vector& r) {
    r.set_box_values(box, b_values);
    r.assemble();
    matvec(-1.0, A, x, 1.0, r);
    std::vector<double> rv;
    r.get_box_values(box, rv);
    return global_norm(rv, comm) / b_norm;
}

TrueResidualSolve solve_to_true_residual(MPI_Comm comm, Solver& solver, const Matrix& A, const Vector& b, Vector& x,
                                         std::vector<double>& b_values, double b_norm, const Box& box, Vector& r,
                                         double tolerance, int max_iterations) {
    TrueResidualSolve out;
    double tol_round = tolerance;
    int left = max_iterations;
    for (int round = 0; round < 6 && left > 0; ++round) {
        solver.set_tolerance(tol_round);
        solver.set_max_iterations(left);
        solver.solve(A, b, x);
        const int its = solver.iterations();
        out.iterations += its;
        left -= its;
        out.reported_residual = solver.final_relative_residual();
        out.true_residual = true_relative_residual(comm, A, x, b_values, b_norm, box, r);
        out.rounds.emplace_back(out.iterations, out.true_residual);
        if (out.true_residual <= tolerance) {
            out.converged = true;
            break;
        }
        if (!std::isfinite(out.true_residual)) break;
        out.restarts = round + 1;
        // The recursive residual drifted from the true one: aim lower by the observed ratio.
        tol_round *= 0.5 * tolerance / out.true_residual;
    }
    return out;
}

}  // namespace nimbus::diffusion::hypre
