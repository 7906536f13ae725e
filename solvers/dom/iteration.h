// The outer iteration of one band: source iteration, optionally accelerated by DSA (dsa.h).
//   phi^{l+1/2} = sweep( kappa* a* Σ chi_l Y phi^l + Q )            (transport_sweep.h)
//   phi^{l+1}   = phi^{l+1/2} (+ DSA correction of the scalar flux)
// stopping when the relative change of the scalar fluence F = Σ_n w_n psi_n,
//   ||F^{l+1} - F^l||_2 / ||F^{l+1}||_2  (the swept cells below, all ranks; F = sqrt(4π) phi_0
//   where phi is computed, the source rows of transport_sweep.h),
// falls below opt.tolerance. With plain source iteration the error left is about
// tolerance · rho/(1 - rho), rho ≈ a the spectral radius; with DSA rho is small.
// The iterations sweep only the medium's bounding box (TransportSweeper::region; outside it, F
// is 0 in every iterate, so the change is the box's); once converged, one more sweep of the
// whole domain from the last iterate gives the fields, with the light in the void around the
// medium (the sweep after DSA's last correction: a source iteration step, which only reduces the
// error left).
//
// Collective over d.comm(). Returns the history whether or not it converged (the model turns
// non-convergence into an Error); the last sweep's fields are in `out`.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "solvers/dom/band_problem.h"
#include "solvers/dom/transport_sweep.h"
#include "src/core/decomposition.h"
#include "src/core/report.h"
#include "src/model/options.h"

namespace nimbus::dom {

struct IterationResult {
    bool converged = false;
    bool stalled = false;            // stopped early: the iteration diverges (stalled(), blew_up())
    std::string divergence;          // why, when stalled
    int iterations = 0;
    std::vector<double> history;     // relative change after each iteration
    int dsa_linear_iterations = 0;   // PFMG V-cycles, summed over the DSA solves
    double seconds = 0;              // total iteration time (sweeps, moments, DSA)
};

// Source iteration and DSA stop early, not converged, when the iteration diverges: the
// relative change has stayed above kStallGrowth times its earlier minimum for the last
// kStallWindow iterations (checked from iteration 2 kStallWindow on): finishing max_iterations
// would only cost time. DSA correcting the isotropic error alone diverged on strongly
// backscattering media (g = -0.9 at albedo 0.99: the change settled near 1.8); with the current
// corrected too (dsa.h) it converges there, and the stop is the guard for what is left. Slow convergence
// (source iteration at ratio 0.99, DSA's period-6 oscillation on clouds) keeps setting new
// minima, and a change wandering at its round-off floor stays near its minimum: neither stops.
inline constexpr int kStallWindow = 20;
inline constexpr double kStallGrowth = 2.0;
bool stalled(const std::vector<double>& history);

// A divergence stalled() cannot see: the fluence grows by a constant factor G per iteration, so
// the relative change sits at 1 - 1/G and sets no growing record (source iteration with
// model.dom.legendre_order 8 at S4 and g = -0.99: G ~ 3, change ~0.66, until the fluence
// overflowed after ~325 iterations and the change of Inf and NaN passed for convergence). The
// iteration stops as diverging when the fluence's norm (every owned cell, all ranks) exceeds
// kBlowUp times its first iterate's. Converging iterations stay far below: the norm's growth from
// the first iterate is the multiplication of the scattering orders, ~1/(1 - spectral radius)
// (about 100 on the tau-100 cube's source iteration). A fluence that is not finite stops it too.
inline constexpr double kBlowUp = 1e12;
bool blew_up(const std::vector<double>& norms);

// Called after each outer iteration (source iteration, DSA; GMRES: each Krylov iteration) with
// the history so far, on every rank alike; it must not communicate. The model's progress line.
// Whatever it throws is dropped (it may run inside a PETSc callback).
using IterationMonitor = std::function<void(const std::vector<double>& history)>;
// Calls m (if set) with the history, dropping what it throws: progress only, and a throw on one
// rank (only rank 0 logs) would leave the others in the next reduction, or unwind through PETSc.
inline void notify(const IterationMonitor& m, const std::vector<double>& history) noexcept {
    if (!m) return;
    try {
        m(history);
    } catch (...) {
    }
}

// method: "source", "dsa", or the Krylov methods of gmres.h: "gmres" (DSA-preconditioned) and
// "gmres-plain" (no preconditioner, for comparison), which this forwards to gmres_band.
IterationResult iterate_band(const Decomposition& d, TransportSweeper& sweeper, const AngularSet& ang,
                             const BandProblem& p, const std::string& method, double tolerance,
                             int max_iterations, SweepOutput& out, Report& report,
                             const IterationMonitor& monitor = {});

}  // namespace nimbus::dom
