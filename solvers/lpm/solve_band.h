// The light propagation maps iteration for one wavelength band (Fattal 2009 §3.4):
//   U^m   <- first-scatter source: kappa a Σ_l E0_l T_l ∫_{Ω^m} p(ω·w_l) dω / |Ω^m|  (W/(m³ sr))
//            + the volume sources' isotropic emission power/4π in every bin (emission.h)
//   repeat until max |U| < epsilon · max(first-scatter source) or `iterations` rounds:
//     for each map -Z, +Z, +X, -X, +Y, -Y: sweep_map (snapshot Ũ, propagate, deposit)
//     tail "dsa", every round but the last: diffusion synthetic acceleration (below)
//   then the tail (tail.h) estimates what the light still in U would add.
//
// DSA (tail "dsa", the default). The rounds are source iteration on the fluence, phi^{n+1/2} =
// Prop(Q + S phi^n), written in increments: U holds the scattering of the light propagated last
// (S = κ a ∫ p(ω'·ω) · dω'). After round n, U - S(f_{n-1}) is the scattering of the iterate's
// change phi^{n+1/2} - phi^n, and the error's source: its P1 solution f_n (tail.h's solve, not
// clamped) is the correction, phi^{n+1} = phi^{n+1/2} + f_n, and U += S(f_n) - S(f_{n-1}) feeds it
// to the next round, where transport corrects P1's error. The first correction carries the
// current (Q1 and S's 3 g F·ω term: the once-scattered light of a bright forward-scattering cloud
// is far from isotropic); later ones are isotropic, as in plain DSA: with the current, an error's
// short transverse waves grow by up to g a/(1 - a g) per round (5.6 at g 0.85, a 0.999; DOM
// filters it, solvers/dom/dsa.h) and the iteration diverged on the default cloud by round 4. At
// the stop the last S(f) is taken out again and the diffusion tail solves for what is left, so
// the fields equal phi^{n+1/2} + P1(the error's source) and every S(f) added is removed once (the
// energy bookkeeping below closes unchanged). The fixed point is LPM's converged answer.
// The reduced sun E0 T is not propagated (it is fluence_reduced); only light scattered at
// least once is, so fluence = ∫ I_d dω (DESIGN §1); emitted light is diffuse light from the
// start. Collective over d.comm(); slabs along z.
//
// Energy bookkeeping (watts, global sums), exact to round-off for any iteration count:
//   source = Σ_cells V (kappa a Σ_l E0_l T_l + power)  =  escaped + absorbed + remaining + truncated,
//   absorbed = Σ V (1 - a) kappa φ,  remaining = Σ V Σ_m |Ω^m| U^m (unpropagated at the end),
// all measured BEFORE the tail (opt.tail, tail.h) adds its estimate of what `remaining` would
// still contribute to the fluence (and flux).
#pragma once

#include <vector>

#include "solvers/lpm/angular.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/progress.h"
#include "src/core/report.h"
#include "src/model/model.h"
#include "src/model/options.h"
#include "src/scene/emission.h"
#include "src/scene/medium.h"
#include "src/scene/scene.h"

namespace nimbus::lpm {

struct BandResult {
    Field<double> fluence;        // ∫ I_d dω, W/m², owned + 1 ghost (halo-exchanged)
    Field<double> flux;           // F, 3 comps, owned + 1 ghost; empty unless solution_bins == 4
    int iterations = 0;
    std::vector<double> max_U;    // after each iteration, relative to the first-scatter maximum
    std::vector<double> sweep_seconds;  // wall time of every map sweep (this rank)
    double wait_seconds = 0.0;    // blocked on neighbours (this rank)
    double source = 0.0, escaped = 0.0, absorbed = 0.0, remaining = 0.0;  // W, global
    double escaped_face[3][2] = {};  // W through the domain face [axis][low, high], global
    double truncated = 0.0;          // W left undeposited by cyclic sweeps of periodic axes, global
    std::vector<double> remaining_history;  // W unpropagated after each iteration, global
    double tail_factor = 0.0;        // geometric tail: rho/(1-rho) applied to the last increment
    int tail_solver_iterations = 0;  // diffusion tail: linear-solver iterations
    int dsa_corrections = 0;         // tail "dsa": P1 corrections fed back (one per round but the last)
    int dsa_solver_iterations = 0;   // their linear-solver iterations, summed
    // Tail "dsa" only: when max |U| grew from one round to the next (DSA diverging), its history
    // up to there; this result is then the solve with tail "diffusion" (solve_sources).
    std::vector<double> dsa_diverged_max_U;
    // The first-scatter source's bound (FirstScatterMeans), for the caller to report.
    FirstScatterBound first_scatter;
};

// The map order of one iteration: faces -Z, +Z, +X, -X, +Y, -Y.
inline constexpr int kMapOrder[6] = {5, 4, 0, 1, 2, 3};

// Collective. m.rho must have its ghost layer exchanged; light.tau_rho per light term.
// The problem has optics bo and the source terms at the given strengths (band_groups.h order:
// E0 of each light of `light` in W/m², then each volume source's power in W/m³); terms of
// strength 0 are left out. report: receives the diffusion tail's solver record (a scratch report
// when null). progress: advanced by one per map sweep from progress_offset.
BandResult solve_sources(const Decomposition& d, const Medium& m, const LightTransport& light, const BandOptics& bo,
                         const std::vector<double>& strength, const LpmOptions& opt, const Angular& ang,
                         Progress* progress, double progress_offset, Report* report,
                         const std::vector<VolumeSource>& sources);

// Band `band` of m with its own light and emission (sources: the scene's volume sources,
// volume_sources; none by default).
BandResult solve_band(const Decomposition& d, const Medium& m, const LightTransport& light, int band,
                      const LpmOptions& opt, const Angular& ang, Progress* progress = nullptr,
                      Report* report = nullptr, const std::vector<VolumeSource>& sources = {});

}  // namespace nimbus::lpm
