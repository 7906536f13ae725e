// Krylov iteration of one band: the transport problem written on the scattering moments,
//   (I - K) phi = b,   K phi = D L^{-1} M (sigma_s chi ∘ phi),   b = D L^{-1} Q,
// where L^{-1} is a transport sweep (transport_sweep.h), M moments-to-directions and D
// directions-to-moments, solved by PETSc KSPGMRES (restart 30) with a MatShell whose MatMult is
// x - sweep(x) (Adams & Larsen 2002 §5; Warsa, Wareing & Morel 2004).
//
// Preconditioner (GmresPreconditioner::dsa, the default): DSA (dsa.h) as a left PCShell.
// One DSA step x' = x + (I + C)(b - (I - K) x) is a Richardson step on
//   P^{-1} (I - K) phi = P^{-1} b,   P^{-1} r = r + e_0 δ(r_0, r_1) + e_1 δF(r_0, r_1)
// where δ and δF are DSA's corrections (dsa.h) of the fluence change r_0 and the flux change r_1,
// read from the Y_00 and Y_1m moments of r (constant factors between moment and fluence units,
// undone on the way back; the map is linear: the current's filter is a fixed PFMG cycle). GMRES on this system
// converges in a handful of iterations where source iteration needs thousands (thick cube,
// tests/verification/dom/iteration_test.cpp). The DSA solve inside the preconditioner is two
// PFMG V-cycles from zero (DiffusionSynthetic::kVCycles), so P^{-1} is exactly linear, as
// GMRES needs. Until the twenty-eighth session it was PFMG-PCG to min(1e-4, 1e-2 tolerance),
// linear only to that tolerance (loosened to 1e-3 .. 0.1, the tau-100 cube's answer moved
// 2.8e-5 .. 8.1e-4 of its peak) and about 7.5 PCG iterations per application on the default
// cloud; the two cycles take the same GMRES iterations on every test and on the default cloud
// (one cycle: 7 + 6 instead of 6 + 6 on the cloud, 8 instead of 7 on the g = -0.5 cube, and the
// cloud's answer moved 4e-5, rel L2, against 4e-6 with two).
//
// Stopping: the same kind of quantity as source iteration and DSA (iteration.h), the relative
// change a Richardson step would make, ||P^{-1} (b - (I - K) phi_k)||_2 <= tolerance ||phi_k||_2
// (P = I without preconditioner: the plain residual, which is source iteration's change). phi_k
// is built from the Krylov basis at each iteration (no sweep). Norms over all moments of the
// cells in the source rows (transport_sweep.h), where source iteration and DSA take the fluence
// of every cell (the Y_00 moment dominates both).
// The Krylov vectors hold the moments of the source rows' cells only, packed: elsewhere sigma_s
// is 0, so those moments feed no source (12.4% of the default cloud's cells; with the moments of
// the sweeps packed too, peak memory per rank 1146 -> 484 MiB on it at 2 ranks).
// b costs one sweep of the external (first-collision + emission) source; the initial guess is 0;
// a last sweep from the converged moments yields the fluence, flux and leakage in `out`. Every
// sweep but that last one covers only the medium's bounding box (TransportSweeper::region),
// which gives the same moments (the Krylov vectors live on the source rows, inside it). Sweeps
// per band: iterations + 2 (b, the last one; + 1 per GMRES restart); DSA solves: iterations + 1.
// The history is the relative change per Krylov iteration (passed to `monitor` as each is
// recorded); dsa_linear_iterations counts the preconditioner's V-cycles (two per DSA solve).
//
// Collective over d.comm(). PETSc is initialized on first use if the program has not.
// Throws Error (every rank) when DSA's right-hand side is not finite; non-convergence is
// returned (converged false).
#pragma once

#include "solvers/dom/iteration.h"

namespace nimbus::dom {

enum class GmresPreconditioner { none, dsa };

IterationResult gmres_band(const Decomposition& d, TransportSweeper& sweeper, const AngularSet& ang,
                           const BandProblem& p, double tolerance, int max_iterations, SweepOutput& out,
                           Report& report, GmresPreconditioner preconditioner = GmresPreconditioner::dsa,
                           const IterationMonitor& monitor = {});

}  // namespace nimbus::dom
