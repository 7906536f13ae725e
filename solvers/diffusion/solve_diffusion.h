// Driver of one diffusion system (diffusion_kernel.h): finds the solve region, assembles and
// solves with the back end named by opt.solver, and returns U and the flux F on the rank's box.
//
// Collective over d.comm(). p's fields live on d.local(); p.kappa_tr and p.G must have their
// ghost layer exchanged (exchange_halo). Appends one record per right-hand side to
// report.values()["diffusion"]["systems"] and times "assemble", "setup", "solve" under the
// caller's open ScopedTimer. Throws Error on every rank when the solve does not converge.
#pragma once

#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/decomposition.h"
#include "src/core/report.h"
#include "src/model/options.h"

namespace nimbus::diffusion {

DiffusionResult solve_diffusion(const Decomposition& d, const DiffusionProblem& p,
                                const DiffusionOptions& opt, Report& report);

}  // namespace nimbus::diffusion
