// The batch a rank is tracing in the forward Monte Carlo model (forward.h): its per-band cell
// tallies, energy counters and photon/collision/segment counts, kept apart until the round
// decides whether the batch is kept (folded into KeptBatches) or dropped (a batch the time
// budget cut). Not collective; one per rank.
//
// Tallies cost O(cells touched), not O(grid): trace_photons (trace_light.h) lists the voxels
// whose accumulator it lit; after each run of consecutive light terms of one colour (the sky's
// directions share one: each term's track is scaled by its power relative to the run's first
// term) they are folded into the per-band batch tally (x P/h² per band) and zeroed, and the
// cells of the batch tally are listed again for end(). A list longer than 1/8 of the padded grid (ForwardSettings::fold_scan_fraction) is
// visited by scanning the grid instead,
// which streams through memory where the list's scattered entries miss the cache; each cell's
// fold is independent of the others', so both give bit-identical tallies (only the term's total
// track, summed over the cells for the diffuse_volume counter, is summed in the visiting order
// and may differ in its last bits). The flux (ForwardSettings::tally_flux; a collision
// estimator, photon.h) goes the same way: the kernels add w s d / kappa per collision to an
// accumulator of 4 doubles per cell, folded with the fluence (x the same P/h²) into the batch's
// flux tally or, in a run whose batches are all kept (no time budget, no target error),
// straight into the kept sums (KeptBatches::fsum).
#pragma once

#include <cstdint>
#include <vector>

#include "solvers/montecarlo/forward.h"
#include "solvers/montecarlo/replicated_problem.h"
#include "src/core/huge_pages.h"

namespace nimbus::mc {

// The sums over the kept batches, per padded cell and band ([cell][band], ReplicatedProblem::
// box_index), and the kept batches' counts.
struct KeptBatches {
    std::vector<double> sum, sumsq;    // of each batch's fluence estimate
    std::vector<double> rsum, rsumsq;  // of the reduced (unscattered) fluence, with tally_reduced
    std::vector<double> fsum;          // of each batch's flux estimate, [cell][band][axis] (tally_flux)
    std::int64_t photons = 0, collisions = 0, segments = 0;
    KeptBatches(const ReplicatedProblem& p, const ForwardSettings& settings);
};

class BatchInFlight {
public:
    // Tracing accumulates in p's voxels (Voxel::tally) and zeroes them again before trace()
    // returns; p must outlive the batch. lanes: trace with the lane kernel (trace_lanes.h) where
    // the settings allow it (not with the forced first collision or the reduced tally). kept:
    // the sums end() folds into (it must outlive the batch); without a time budget and a target
    // error every batch is kept, so the flux (which has no standard error) is folded straight
    // into kept.fsum, skipping the batch's own flux tally and its pass in end().
    BatchInFlight(ReplicatedProblem& p, const MonteCarloOptions& opt, const ForwardSettings& settings, bool lanes,
                  KeptBatches& kept);

    // Traces part [k0, k1) of the `steps` steps of `batch` (of `layout` batches) into the batch:
    // of every term with N photons, the photons [lo + (hi - lo) k0 / steps, lo + (hi - lo) k1 /
    // steps) of its batch range [lo, hi) = [batch N / layout, (batch + 1) N / layout). k0 = 0
    // also books the batch's incident power and the rays that miss the box.
    void trace(int batch, int layout, std::int64_t k0, std::int64_t k1, std::int64_t steps);

    // Folds the batch into the kept sums (keep) or drops it; the batch in flight is empty
    // afterwards. keep is true for every batch of a run without time budget and target error.
    void end(bool keep);

    // The batch's energy counters per band (W), so far.
    const std::vector<Counters>& counters() const { return counters_; }

private:
    // Consecutive light terms of one colour, traced into the voxel accumulators before one fold.
    struct FoldClass {
        bool open = false;
        double P[64]{}, scale[64]{};  // the first term's photon power and fluence scale per band
        int strongest = 0;
        // Opens the class with this term (returns 1), or returns the term's scale ratio alpha to
        // the open class when its scales are proportional, else 0 (the caller folds and reopens).
        double join(int nbg, const double* P_term, const double* scale_term, int strongest_term);
    };
    void fold_class(FoldClass& fc, const GridView& grid, const int* band, int nbg);

    template <class Visit>
    void for_each_listed(const std::vector<std::int64_t>& list, Visit&& visit) const;

    ReplicatedProblem& p_;
    const MonteCarloOptions& opt_;
    const ForwardSettings& settings_;
    KeptBatches& kept_;
    std::vector<double> tally_, rtally_;  // [cell][band] of the batch (rtally_: reduced tally)
    std::vector<double> reduced_acc_;     // the light term's reduced track per cell (tally_reduced)
    std::vector<double> flux_;  // [cell][band][axis] of the batch (tally_flux), when batches may
                                // be dropped; else folded straight into kept_.fsum
    std::vector<double, HugePageAllocator<double>> flux_acc_;  // the fold class's collision
                                                               // sums, [cell][4] (trace_light.h)
    std::vector<std::int64_t> touched_, light_touched_;  // cells tallied in the batch / by the term
    std::vector<Counters> counters_;
    std::int64_t photons_ = 0, collisions_ = 0, segments_ = 0;
    bool lanes_ = false;
};

}  // namespace nimbus::mc
