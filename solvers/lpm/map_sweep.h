// One sweep of one light propagation map across the slab chain (Fattal 2009 §3.2-3.4, the
// body of the pseudocode's "for each map" loop). Collective over d.comm(); requires slabs
// along z (process grid 1 x 1 x P, z not periodic).
//
// The map of face f (axis a, sign s) is a 2-D array of rays per map direction n (p x p),
// R x R rays per cell face (R = refinement), stepping one cell layer along a per step. A ray of
// tangents (t_u, t_v) moves by (t_u, t_v) cells in-plane per step, so it meets at most two
// in-plane faces: 1 to 3 segments per step, each integrated exactly (segment_kernel.h). Rays
// are stored by the slot they occupy at the start of a step (position (q + phi) h/R with one
// phi per direction and step); advancing a step re-indexes slots (q -> q + ΔS), never
// interpolates, so a beam keeps its profile exactly (no false scattering). Rays leaving the
// domain sideways carry their power out (counted in `escaped`); entering rays start at L = 0
// (vacuum: no diffuse light comes in; the sun enters as the first-scatter source in U).
// Periodic x/y wrap instead. Along a periodic map axis (n cells) the map is swept around
// (rays leaving the far face re-enter at the near one), driven by Ũ on every pass: filling
// passes (no deposits, no escapes counted) until the map holds the periodic steady state (the
// light it still lacks from its dark start below 1e-9 of its power, or 100 passes), then one
// lattice cycle of K = p / gcd(p, n R) passes is recorded, each with weight 1/K: a pass moves
// a direction's ray lattice by n t R slots, back onto the same sub-slot offsets only after K
// passes. (The paper's cyclic mapping, source on the first pass only and every pass recorded,
// is exact only for K = 1: see sweep_lateral in map_sweep.cpp and the README.) What the map
// gains over the recorded cycle, / K, is `truncated` (~0 once steady; e.g. horizontal rays of
// odd p in a thin periodic layer, which attenuate slowly, may not be).
//
// Scattering is explicit (§3.3): rays are driven by the snapshot Ũ^m of the face's coarse bins
// taken when the sweep starts (those bins of U are then emptied: all their light is carried by
// this sweep), and the light the medium takes from the rays, kappa ∫L ds per cell and
// direction, is deposited as fluence (and flux) and, times the albedo, into every coarse bin
// m' of U through the form factors: U^{m'} += sigma_s Σ_n P^{n,m'}/|Ω^{m'}| φ_n (eq. 5).
//
// Distribution (issue item 2; no replicated 3-D field):
//   ±Z maps travel down (or up) the slab chain, pipelined over direction groups (one group =
//   one row of p directions): within a sweep the directions are independent (scattering only
//   fills U), so a rank sends group g's map downstream as soon as it has crossed its slab and
//   the next rank starts after 1/p of the work instead of the whole slab.
//   ±X/±Y maps cross every slab at once; each step the rays whose slot leaves the rank's z range
//   are exchanged with the z neighbours (one message per neighbour and step, all directions
//   batched). A ray that crosses a slab boundary inside a step deposits into the ghost layer,
//   which is added to its owner after the sweep.
#pragma once

#include <vector>

#include "solvers/lpm/angular.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus::lpm {

struct MapInputs {
    const Angular* angular = nullptr;
    int refinement = 1;                    // R: rays per cell along each map axis
    double h = 1.0;                        // cell edge, metres
    const Field<double>* kappa = nullptr;  // extinction 1/m, owned + 1 ghost (z ghosts filled)
    double albedo = 0.0;
    const std::vector<double>* deposit = nullptr;  // [map_bins][coarse_bins]: P^{n,m}/|Ω^m|
    bool flux = false;                     // also accumulate the first moment F
};

struct MapAccumulators {
    Field<double>* U = nullptr;        // coarse_bins comps, W/(m³ sr); owned + 1 ghost
    Field<double>* fluence = nullptr;  // W/m²; owned + 1 ghost (ghost used as scratch)
    Field<double>* flux = nullptr;     // 3 comps, or null
    double escaped[3][2] = {};         // W leaving the domain through its [axis][low, high] face
                                       // (this rank's share), accumulated
    double truncated = 0.0;            // W a cyclic (periodic-axis) sweep's map gained over its
                                       // recorded passes (/ K): not yet deposited
    double wait_seconds = 0.0;         // blocked on neighbours (pipeline fill, exchange)
};

// Collective. Sweeps map face f (0..5 = +X, -X, +Y, -Y, +Z, -Z) once.
void sweep_map(const Decomposition& d, int face, const MapInputs& in, MapAccumulators& acc);

}  // namespace nimbus::lpm
