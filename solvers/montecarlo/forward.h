// Forward light tracing driver (issue 3): photons from every light term and every volume
// source (emitter.h, src/scene/emission.h), batches of photon
// index ranges spread over the ranks, per-cell batch-means statistics, energy bookkeeping.
//
// Parallel layout: the density grid is replicated on every rank (MPI_Allgatherv of the owned
// boxes); batch b of light l is the photon index range [b N_l / B, (b+1) N_l / B); every photon
// draws from a Philox stream keyed by (seed, light, photon index), so the same seed gives the
// same result for any rank count (up to the round-off of the final sums). Batches run in
// rounds of one batch per rank; between rounds the stop criteria (photon count, time budget,
// target relative error of the total diffuse power) are decided collectively. Tallies are
// reduced to the owner of each box (MPI_Reduce_scatter), only over cells with density (the
// fluence of empty cells is 0 by contract). The diffuse flux (ForwardResult::flux, a collision
// estimator: photon.h) goes the same way, without a standard error; it is 0 in empty cells too.
//
// Time budget (opt.time_budget): a rank traces its batch in chunks of photon indices (about
// kChunkSeconds each) and stops it at the budget's deadline, which all ranks share (measured
// from the earliest rank's entry); the round that meets the deadline is the last. A batch the
// deadline cut is dropped, and so is any batch after it in the round, so the result is always
// that of the first `batches` complete batches of the layout: equal to round-off (the chunks
// only change the order of the sums) to a budget-free run of the same photons, which is
// `photons` photons in `batches` batches when every batch of every term holds the same photon
// count (N_l divisible by the layout's batch count). Batches 0 and 1 always complete (the
// standard error needs two). In round 0 a pilot measures how long a batch takes; when too few
// batches would fit in the budget, the batches are split (batch_split) and round 0 is traced
// again, so the budget holds whatever the photon count. Overshoot: one chunk plus the final
// reduction (and batches 0 and 1 when even they do not fit).
//
// Photons start only on the live pixels of the medium's bounding box (photon.h, EntrySampler::
// restrict_to); the rest of the domain's projected area is booked as direct escape.
//
// Light terms and volume sources share the photon budget in proportion to their power summed
// over bands (photons_per_light over lights then sources; a source's power is power[b] times
// its emitting volume); source s draws from the Philox stream number lights.size() + s.
//
// Each batch is a full estimate (its photons carry power E0 A_projected / n_batch); the result
// is the mean over the completed batches and the standard error is that of the batch means.
// Bands sharing (sigma_t, albedo, g) are traced once; the tally carries one value per band.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/model/options.h"
#include "src/physics/lights.h"
#include "src/scene/emission.h"
#include "src/scene/medium.h"

namespace nimbus::mc {

// Energy bookkeeping per band, in watts (power through/into the whole domain).
enum Counter : int {
    incident = 0,     // E0 A_projected summed over lights
    absorbed,         // deposited by implicit capture
    escaped_direct,   // left without scattering (the transmitted direct beam; with the forced
                      // first collision booked as its expected value exp(-tau_tot) per path)
    escaped_xlo, escaped_xhi, escaped_ylo, escaped_yhi, escaped_zlo, escaped_zhi,  // scattered light out
    roulette_net,     // weight created minus destroyed by Russian roulette (zero on average)
    diffuse_volume,   // ∫ fluence_diffuse dV over the cells with density (W m; with empty_cells the
                      // empty cells' fluence is not in it): the quantity of the target error
    emitted,          // power of the volume sources (W); balance: incident + emitted =
                      // absorbed + escaped_direct + Σ escaped_faces (+ roulette_net, zero mean)
    ncounters
};
using Counters = std::array<double, ncounters>;

struct ForwardSettings {
    bool tally_reduced = false;  // also tally the unscattered fluence (verification only)
    // Force the first collision on every entry ray (photon.h). Unbiased; off because on the
    // default cloud it costs ~30% more instructions per collision for ~4% less variance per
    // cell: the live-pixel entry (photon.h) already drops the rays that meet no medium.
    bool forced_first_collision = false;
    // Touched-cell lists longer than 1/fold_scan_fraction of the padded grid are folded by a
    // scan of the grid (batch_in_flight.h); 0: always by the list. Changes speed, not fields.
    std::int64_t fold_scan_fraction = 8;
    // Consecutive light terms of one colour share the voxel accumulators and one fold
    // (batch_in_flight.h); false: a fold per term. Changes speed and rounding, not the estimate.
    bool fold_by_colour = true;
    // Tally the diffuse flux F (ForwardResult::flux; the collision estimator, photon.h). Off:
    // the kernels skip it (MonteCarloOptions::flux = false, the model's default: 10-12% more
    // collisions per second).
    bool tally_flux = true;
};

struct ForwardResult {
    // Per band, on the rank's owned box + 1 ghost (halo-exchanged), W/m².
    std::vector<Field<double>> fluence, fluence_stderr;
    std::vector<Field<double>> reduced, reduced_stderr;  // only with tally_reduced
    // Per band, 3 components, owned box + 1 ghost (halo-exchanged), W/m²: the cell mean of the
    // diffuse flux F = ∫ I_d w dw, the batch mean (no standard error); only with tally_flux.
    std::vector<Field<double>> flux;
    // Per band, over the whole domain (same on every rank): batch mean and its standard error.
    std::vector<Counters> counters, counters_stderr;
    std::int64_t photons = 0, collisions = 0;  // totals over all ranks
    std::int64_t segments = 0;                 // tallied diffuse track segments, all ranks (the walk's work)
    int batches = 0;                           // batches completed (and used)
    int layout_batches = 0;                    // batches of the layout: opt.batches, or more when
                                               // the time budget split them (batch_split)
    double seconds = 0.0;                      // wall time of trace_forward (max over ranks)
    double setup_seconds = 0.0;                // (all four: max over ranks) replication, voxel grid, empty space, buffers
    double trace_seconds = 0.0;                // the rounds of batches (incl. per-round reductions,
                                               // and round 0 dropped when the batches were split)
    double reduce_seconds = 0.0;               // counters, sparse tally reduction, halo exchange
    double replicated_gb = 0.0;                // per-rank memory of the replicated arrays
    double rel_error = 0.0;                    // relative standard error of diffuse_volume (all bands);
                                               // NaN when no diffuse power was tallied (unknown)
    std::string stop_reason;                   // "photons", "time_budget", "target_rel_error"
    std::string kernel;                        // the path kernel that traced: "lanes" or "scalar"
};

// Throws Error on every rank when opt.kernel is "lanes" and the CPU of some rank cannot run it
// (trace_lanes.h). Collective over comm.
void check_kernel(MPI_Comm comm, const MonteCarloOptions& opt);
// Whether trace_forward traces with the lane kernel: opt.kernel "lanes", or "auto" on a CPU that
// runs it, and settings without the forced first collision and the reduced tally.
bool uses_lane_kernel(const MonteCarloOptions& opt, const ForwardSettings& settings);

// Bytes per rank of the replicated arrays of trace_forward for a grid (or walked box) of
// `cells` cells: density (gathered + global), the 16-byte voxels per optics group, per band the
// batch tally and its running sum and sum of squares (twice with the reduced tally) and the
// reduce buffer; with the flux, its accumulator (4 doubles) and per band its batch tally (with a
// time budget or a target error), sum and reduce buffer (3 doubles each); plus at most 4 bytes per covered cell of the
// volume sources' cell lists.
inline double replicated_bytes(double cells, int optics_groups, int nbands, bool tally_reduced,
                               double source_cells = 0.0, bool tally_flux = true) {
    const int nq = tally_reduced ? 4 : 2;
    const double flux = tally_flux ? 32.0 + 24.0 * nbands * 3 : 0.0;
    return cells * (16.0 + 16.0 * optics_groups + 8.0 * nbands * (nq / 2) * 3 + 8.0 * nbands * nq + 12.0 + flux) +
           4.0 * source_cells;
}

// Throws Error when `bytes` of replicated arrays (replicated_bytes) of the n[0] x n[1] x n[2]
// grid exceed opt.max_replicated_memory_gb; the run (trace_forward) and the pre-flight check
// (`nimbus info`, the model's check) say the same.
void check_replicated_memory(const std::array<int, 3>& n, double bytes, const MonteCarloOptions& opt);

// Collective over d.comm(). medium.rho must hold the owned box; lights as from make_lights.
// Periodic axes are taken from d.periodic() (photons enter only through non-periodic faces).
// Throws Error (on every rank) if the replicated arrays would exceed
// opt.max_replicated_memory_gb. Lights that cannot enter (e.g. horizontal in a periodic slab)
// carry no photons; with none left the result is zero with stop_reason "no light".
ForwardResult trace_forward(const Decomposition& d, const Medium& medium,
                            const std::vector<DirectionalLight>& lights,
                            const MonteCarloOptions& opt, const ForwardSettings& settings = {});
// The same with volume sources (emission.h; cells without density do not emit). Emitted
// photons escaping uncollided count in escaped_xlo..zhi, not escaped_direct.
ForwardResult trace_forward(const Decomposition& d, const Medium& medium,
                            const std::vector<DirectionalLight>& lights,
                            const std::vector<VolumeSource>& sources,
                            const MonteCarloOptions& opt, const ForwardSettings& settings = {});

// Time to the earliest stop that applies, for the progress log: the photon count (the batches
// left, at the rate so far), the time budget (what is left of it: the run stops there, within a
// chunk), and the target relative error, estimated as rel_error * sqrt(done / k)
// after k batches (the standard error of a mean of k batch estimates falls as 1/sqrt(k));
// the target is left out while rel_error is 0 (no diffuse light yet, no estimate).
// done >= 1 of opt.batches batches (the layout's batch count) took trace_seconds; elapsed:
// seconds since trace_forward began (the time budget's clock). Not collective.
struct StopEta {
    double seconds = 0.0;
    std::string until;  // "photon count", "time budget", "target error (estimated from 1/sqrt(batches))"
};
StopEta eta_to_stop(const MonteCarloOptions& opt, int done, double trace_seconds, double elapsed,
                    double rel_error);

// Time-budget tuning (trace_forward). A budget run traces batches in chunks of about
// kChunkSeconds (or 1/50 of the budget if less), on a grid of kChunkSteps steps per batch; the
// pilot runs for kPilotSeconds (or 1/32 of the budget if less). A batch and a chunk have fixed
// costs (folding the cells they lit into the tallies: ~2 ms a batch and ~2 ms a chunk on the
// default cloud's 96x96x64 grid), hence kMinBatchSeconds.
inline constexpr double kChunkSeconds = 0.05;
inline constexpr std::int64_t kChunkSteps = std::int64_t{1} << 20;
inline constexpr double kPilotSeconds = 1.0;
inline constexpr int kMinBudgetBatches = 8;       // fewer batches fitting in the budget: split them
inline constexpr double kMinBatchSeconds = 0.05;  // but not below this per batch

// The factor by which a time-budget run splits its batches (a power of two; 1 keeps them),
// from the pilot: a batch of the layout takes batch_seconds (a round, one batch per rank),
// seconds_left of the budget remain, `batches` batches on `ranks` ranks. The layout is kept when
// all its batches fit, or at least min(batches, kMinBudgetBatches) do. Otherwise the batches are
// halved until ceil(batches / ranks) + 1 rounds fit (the user's batch count, and a round to
// spare for the one the deadline cuts), while a batch still takes kMinBatchSeconds and
// batches * split <= max_batches (every batch keeps a photon of every term). Not collective.
int batch_split(double batch_seconds, double seconds_left, int batches, int ranks,
                std::int64_t max_batches);

// The fraction of the ranks' time spent tracing when `batches` batches run in rounds of one batch
// per rank on `ranks` ranks (batches of equal cost): batches / (ranks * rounds). The model warns
// below kBusyFractionToWarn (32 batches: 89% on 6 ranks, 67% on 24, 50% on 64).
inline double busy_fraction(int batches, int ranks) {
    const int rounds = (batches + ranks - 1) / ranks;
    return static_cast<double>(batches) / (static_cast<double>(ranks) * rounds);
}
inline constexpr double kBusyFractionToWarn = 0.9;

// target_rel_error is tested from this many batches on (or all of them, if fewer): a standard
// error from 2 batches has one degree of freedom and stopped runs on a lucky pair (reported
// 6e-4 where the 200k photons' error is 3e-3).
inline constexpr int kMinBatchesForTarget = 8;

// Relative standard error of the mean of K batch values with sum s1 and sum of squares s2
// (unbiased sample variance); 0 for K < 2 or a non-positive mean.
double relative_standard_error(double s1, double s2, int K);

// Photon count of each light: proportional to its power summed over bands (E0 A_projected),
// at least `batches` per light that carries power, rounded by largest remainder so that the
// counts sum to `total` exactly (unless the minimum alone exceeds it). Same on every rank.
std::vector<std::int64_t> photons_per_light(const std::vector<double>& power, std::int64_t total,
                                            int batches);

}  // namespace nimbus::mc
