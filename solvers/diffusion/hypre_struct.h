// RAII wrappers of the hypre Struct interface (hypre 2.26) used by the diffusion model:
// grid, the symmetric 7-point stencil, matrix, vector and the solvers PFMG, SMG, PCG with a
// PFMG/SMG preconditioner. Life cycle as in the hypre examples: Create, Set, Assemble
// (collective), Setup (collective), Solve (collective), Destroy (in the destructor).
//
// Every constructor is collective over the communicator it is given. A hypre error (any but
// non-convergence, which the caller judges on the true residual) throws Error; in a collective
// call (Assemble, Setup, Solve, Matvec) on every rank. A rank may own no box:
// it still constructs every object (hypre Struct allows ranks without boxes; SetExtents is
// simply not called). Boxes are nimbus half-open boxes; the conversion to hypre's inclusive
// [ilower, iupper] is done here and nowhere else.
#pragma once

#include <mpi.h>

#include <HYPRE_struct_ls.h>

#include <string>
#include <utility>
#include <vector>

#include "src/core/box.h"

namespace nimbus::diffusion::hypre {

// HYPRE_Init once per process (idempotent).
void ensure_initialized();

class Grid {
public:
    // Collective. box: this rank's cells (may be empty). period[a] > 0 makes axis a periodic
    // with that period. PFMG takes any period (the slab test runs periods 5 and 6); SMG needs a
    // power of two (HYPRE_struct_ls.h): with 24 it gave NaN, so the diffusion model refuses SMG
    // on other periods before the run (diffusion.cpp, DiffusionModel::check).
    Grid(MPI_Comm comm, const Box& box, const Int3& period);
    ~Grid();
    Grid(const Grid&) = delete;
    Grid& operator=(const Grid&) = delete;
    HYPRE_StructGrid get() const { return g_; }

private:
    HYPRE_StructGrid g_ = nullptr;
};

// Symmetric storage of the 7-point stencil: entries 0 = centre, 1 = -x, 2 = -y, 3 = -z; the
// +x/+y/+z couplings are their transposes (HYPRE_StructMatrixSetSymmetric).
class SymmetricStencil7 {
public:
    SymmetricStencil7();
    ~SymmetricStencil7();
    SymmetricStencil7(const SymmetricStencil7&) = delete;
    SymmetricStencil7& operator=(const SymmetricStencil7&) = delete;
    HYPRE_StructStencil get() const { return s_; }
    static constexpr int kEntries = 4;

private:
    HYPRE_StructStencil s_ = nullptr;
};

class Matrix {
public:
    // Collective. Symmetric storage; call set_box_values (own box only) and then assemble().
    Matrix(MPI_Comm comm, const Grid& grid, const SymmetricStencil7& stencil);
    ~Matrix();
    Matrix(const Matrix&) = delete;
    Matrix& operator=(const Matrix&) = delete;
    // values: SymmetricStencil7::kEntries per cell, entries fastest, then x, y, z.
    void set_box_values(const Box& box, std::vector<double>& values);
    void assemble();  // collective
    HYPRE_StructMatrix get() const { return A_; }
    MPI_Comm comm() const { return comm_; }

private:
    MPI_Comm comm_;
    HYPRE_StructMatrix A_ = nullptr;
};

class Vector {
public:
    Vector(MPI_Comm comm, const Grid& grid);  // collective; initialized to 0
    ~Vector();
    Vector(const Vector&) = delete;
    Vector& operator=(const Vector&) = delete;
    void set_box_values(const Box& box, std::vector<double>& values);  // x fastest
    void get_box_values(const Box& box, std::vector<double>& values) const;
    void assemble();  // collective
    HYPRE_StructVector get() const { return v_; }

private:
    MPI_Comm comm_;
    HYPRE_StructVector v_ = nullptr;
};

struct SolverCalls;  // hypre_struct.cpp

// y = alpha A x + beta y (collective).
void matvec(double alpha, const Matrix& A, const Vector& x, double beta, Vector& y);

// One of pfmg | smg | pfmg-pcg | smg-pcg, or pfmg-cycle: one PFMG V-cycle from a zero guess
// with no residual test, set up as PCG's preconditioner (a fixed linear map; DOM's DSA filters
// with it). PCG uses the 2-norm stopping test ||r|| <= tol ||b|| (HYPRE_StructPCGSetTwoNorm).
class Solver {
public:
    // periodic: the grid has a periodic axis (selects a smoother that stays symmetric there).
    Solver(MPI_Comm comm, const std::string& kind, bool periodic);  // collective
    ~Solver();
    Solver(const Solver&) = delete;
    Solver& operator=(const Solver&) = delete;

    void set_tolerance(double tol);
    // hypre allocates its residual logs at setup: never raise the limit after setup().
    void set_max_iterations(int n);
    void setup(const Matrix& A, const Vector& b, Vector& x);  // collective
    void solve(const Matrix& A, const Vector& b, Vector& x);  // collective; x = initial guess
    int iterations() const;
    double final_relative_residual() const;

private:
    MPI_Comm comm_;
    const SolverCalls* calls_ = nullptr;     // solver_'s
    const SolverCalls* mg_calls_ = nullptr;  // the multigrid's: solver_'s or precond_'s
    HYPRE_StructSolver solver_ = nullptr;    // PFMG, SMG or PCG
    HYPRE_StructSolver precond_ = nullptr;   // PFMG or SMG inside PCG
};

// ||v||_2 over all ranks (collective).
double global_norm(const std::vector<double>& v, MPI_Comm comm);

// ||b - A x|| / ||b|| with the matrix itself (hypre's PCG residual is recursive and can
// understate the true one). b_values: b on box (x fastest); r: scratch. Collective.
double true_relative_residual(MPI_Comm comm, const Matrix& A, const Vector& x, std::vector<double>& b_values,
                              double b_norm, const Box& box, Vector& r);

// One solve to a TRUE relative residual: the solver runs from x to a tolerance, the true
// residual is checked, and while it is above `tolerance` the solver restarts from its last
// iterate aiming lower by the observed ratio (at most 6 rounds, max_iterations in all).
struct TrueResidualSolve {
    bool converged = false;
    int iterations = 0;
    int restarts = 0;
    double reported_residual = 0.0;  // the solver's own, last round
    double true_residual = 0.0;
    std::vector<std::pair<int, double>> rounds;  // iterations so far, true residual, per round
};
TrueResidualSolve solve_to_true_residual(MPI_Comm comm, Solver& solver, const Matrix& A, const Vector& b, Vector& x,
                                         std::vector<double>& b_values, double b_norm, const Box& box, Vector& r,
                                         double tolerance, int max_iterations);

}  // namespace nimbus::diffusion::hypre
