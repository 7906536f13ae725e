// Work-balanced slabs for the exact light pass's chain (exact_chain.h).
//
// On the field's even z slabs the rank nearest the light traces a piece of every ray that
// crosses its slab: in a uniform medium under a vertical sun its share of the walk is
// (2P - 1)/P² (3/4 on 2 ranks, tending to 2/P), so P ranks run the pass at most P²/(2P - 1)
// times faster than one (1.33 on 2 ranks, tending to P/2). The pass therefore runs on slabs of its own
// (Decomposition::with_cuts), cut where the work is even, with the density moved there and
// each τ moved back (src/core/relayout.h).
//
// The work is measured, not modelled from the density: a pilot traces a sample of the rays
// (the cells of every `stride`-th column in x and y) on the field's slabs, exactly as the chain
// would, and counts the walk's voxel reads per z layer (grid_walk.h's on_step). Counts, not
// times, so the cuts, and with them τ's round-off, are the same in every run on the same ranks.
// A slab's cost is then
//   cost[lo, hi) = Σ_{k in [lo, hi)} steps[k] + s · (rays starting in [lo, hi) + rays entering it
//                  from downstream through its entry face),
// s = kPieceSetupSteps the set-up of one ray piece in voxel reads (measured, see below), and the
// cuts minimise the largest slab cost (bisection on the bound, greedy slabs from the light).
#pragma once

#include <vector>

#include "solvers/light/exact_chain.h"
#include "src/core/decomposition.h"
#include "src/physics/lights.h"

namespace nimbus {

// The cost of one ray piece beyond its voxel reads (ray_start, the walk's set-up and exit, the
// partial sum's store, message and addition), in voxel reads. Fitted by least squares to each
// rank's tracing time against its slab's counted reads and pieces, 2 ranks, cuts moved by hand:
// default cloud (96x96x64, cuts 24-48) 3.1 ns per read and 95 ns per piece, a ratio of 30;
// its 128³ version (cuts 56-80) 2.1 and 134 ns, a ratio of 64 (the pieces' first reads miss
// the cache more on the larger grid). Single timings scatter by ±15% on this machine, so 50
// sits between the two: it puts the cuts within 2-3 layers of either fit's.
inline constexpr double kPieceSetupSteps = 50.0;

// Sampled work of the chain for lights on one side of the domain (all toward +z, or all toward
// -z: the rays' direction b = -w toward the light).
struct ChainWork {
    bool toward_high_z = true;    // the rays run toward +z (the light is above)
    std::vector<double> steps;    // per z layer: voxel reads of the sampled rays' walks in it
    std::vector<double> starts;   // per z layer: sampled rays starting there
    std::vector<double> entering; // per z face f = 0..nz: sampled rays crossing f from downstream
    std::int64_t rays = 0;        // sampled rays (all lights)

    // The cost of a slab of layers [lo, hi) (in voxel reads of the sample).
    double slab_cost(int lo, int hi, double setup = kPieceSetupSteps) const;
    // Largest and mean slab cost over the slabs of `cuts` (z order, parts + 1 values).
    double max_cost(const std::vector<int>& cuts, double setup = kPieceSetupSteps) const;
    double mean_cost(const std::vector<int>& cuts, double setup = kPieceSetupSteps) const;
};

// Collective over d.comm() (slabs along z). The pilot: traces, on this rank's field slab
// `slab` (make_slab_grid), its pieces of the sampled rays of every light in `lights` (all with
// b.z of one sign), and sums the counts over the ranks.
ChainWork sample_chain_work(const Decomposition& d, RayGrid& slab, const std::vector<DirectionalLight>& lights,
                            int stride);

// The sample stride for a domain of n cells: min(n_x, n_y) / 8 (at least 1), so about 64 columns
// of rays a layer whatever the grid (stride 32 at 256³: the pilot took 0.16-0.22 s of a 24.5 s
// pass on 2 ranks; with the stride capped at 12, 0.93-0.97 s).
int pilot_stride(const Int3& n);

// Cuts of the z layers into `parts` slabs (parts + 1 values, 0 ... nz, each slab at least one
// layer) minimising the largest slab_cost. Pure; needs nz >= parts.
std::vector<int> balanced_cuts(const ChainWork& w, int parts, double setup = kPieceSetupSteps);

}  // namespace nimbus
