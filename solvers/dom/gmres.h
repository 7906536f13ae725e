// Krylov iteration of one band: the transport problem written on the scattering moments,
//   (I - K) phi = b,   K phi = D L^{-1} M (sigma_s chi ∘ phi),   b = D L^{-1} Q,
// where L^{-1} is a transport sweep (transport_sweep.h), M moments-to-directions and D
// directions-to-moments, solved by PETSc KSPGMRES (restart 30, no preconditioner) with a
// MatShell whose MatMult is x - sweep(x) (Adams & Larsen 2002 §5; Warsa, Wareing & Morel 2004).
// b costs one sweep of the external (first-collision + emission) source; a last sweep from the
// converged moments yields the fluence, flux and leakage in `out`. Stops when the
// unpreconditioned residual satisfies ||b - (I - K) phi||_2 <= tolerance ||b||_2.
// The history is the relative residual per Krylov iteration.
//
// Collective over d.comm(). PETSc is initialized on first use if the program has not.
#pragma once

#include "solvers/dom/iteration.h"

namespace nimbus::dom {

IterationResult gmres_band(const Decomposition& d, TransportSweeper& sweeper, const AngularSet& ang,
                           const BandProblem& p, double tolerance, int max_iterations, SweepOutput& out,
                           Report& report);

}  // namespace nimbus::dom
