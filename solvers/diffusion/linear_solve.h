// The two linear-algebra back ends of the diffusion model. Both take the assembled rows
// (Assembler) on the solve region and return, per right-hand side, the solution on this
// rank's part of the region, x fastest. Both check the TRUE relative residual ||b-Ax||/||b||
// after the solve and throw Error on every rank, with the residual history, when it is above
// the tolerance after max_iterations.
//
//   hypre: Struct interface, one box per rank (d.local() ∩ region, possibly empty), symmetric
//          7-point storage, pfmg | smg | pfmg-pcg | smg-pcg. Matrix and setup shared by all
//          right-hand sides.
//   petsc: DMDA over the whole domain with the decomposition's ownership (slabs along z
//          only), KSP CG with PCHYPRE BoomerAMG, unpreconditioned 2-norm stopping test. For
//          cross-checks; cells outside the region are empty (identity rows).
//
// Collective over d.comm(). Times "assemble", "setup", "solve" into report under the caller's
// open ScopedTimer (the model opens "diffusion").
#pragma once

#include <vector>

#include "solvers/diffusion/assemble.h"
#include "src/core/decomposition.h"
#include "src/core/report.h"
#include "src/model/options.h"

namespace nimbus::diffusion {

struct LinearSolveOutput {
    Box box;                               // d.local() ∩ region
    std::vector<std::vector<double>> x;    // per rhs, on box, x fastest
    std::vector<SolveStats> stats;         // per rhs
};

LinearSolveOutput solve_with_hypre(const Decomposition& d, const Assembler& assembler,
                                   const DiffusionProblem& p, const SolveRegion& region,
                                   const DiffusionOptions& opt, Report& report);

LinearSolveOutput solve_with_petsc(const Decomposition& d, const Assembler& assembler,
                                   const DiffusionProblem& p, const SolveRegion& region,
                                   const DiffusionOptions& opt, Report& report);

// Collective over d.comm(). Throws, before anything is computed, the Error solve_with_petsc
// would throw for this decomposition (slabs along z) or for model.diffusion.petsc_options,
// which it reads as the solve does (the DMDA on d's grid, a KSP without a matrix): words PETSc
// would drop, options without the prefix -diffusion_, and values PETSc rejects, naming the first
// option that fails. What only KSPSetUp or KSPSolve read is checked by the solve, which also
// refuses options that no object has read by the end of its first KSPSolve.
void check_petsc(const Decomposition& d, const DiffusionOptions& opt);
// The decomposition part of check_petsc (slabs along z), without communication.
void check_petsc_layout(const Decomposition& d);

}  // namespace nimbus::diffusion
