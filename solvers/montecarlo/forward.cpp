#include "solvers/montecarlo/forward.h"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include "solvers/montecarlo/batch_in_flight.h"
#include "solvers/montecarlo/replicated_problem.h"
#include "solvers/montecarlo/trace_lanes.h"
#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/log.h"
#include "src/core/mpi_counts.h"
#include "src/core/progress.h"
#include "src/core/report.h"
#include "src/scene/optics_groups.h"

namespace nimbus::mc {

std::vector<std::int64_t> photons_per_light(const std::vector<double>& power, std::int64_t total,
                                            int batches) {
    std::vector<std::int64_t> n(power.size(), 0);
    std::vector<bool> free(power.size(), false);  // not (yet) held at the minimum
    for (size_t l = 0; l < power.size(); ++l) free[l] = power[l] > 0;
    // Shares relative to the largest power, so that the sums below cannot overflow.
    const double pmax = power.empty() ? 0.0 : *std::max_element(power.begin(), power.end());
    if (!(pmax < std::numeric_limits<double>::infinity()))
        throw Error(fmt::format("montecarlo: light powers must be finite (largest {} W)", pmax));
    std::vector<double> rel(power.size(), 0.0);
    for (size_t l = 0; l < power.size(); ++l) rel[l] = pmax > 0 ? power[l] / pmax : 0.0;
    // Lights whose share falls below the minimum get exactly `batches`; the rest share what is
    // left in proportion to their power (repeat until no share falls below the minimum).
    for (;;) {
        double sum = 0.0;
        std::int64_t left = total;
        for (size_t l = 0; l < power.size(); ++l) {
            if (free[l]) sum += rel[l];
            else if (power[l] > 0) left -= batches;
        }
        if (sum <= 0) break;
        bool changed = false;
        for (size_t l = 0; l < power.size(); ++l)
            if (free[l] && static_cast<double>(left) * rel[l] / sum < batches) free[l] = false, changed = true;
        if (changed) continue;
        // Largest remainder: floor of each share, the leftover photons one each to the largest
        // fractional parts (ties to the lower index), so the counts sum to `total` exactly.
        std::vector<std::pair<double, size_t>> rem;
        std::int64_t assigned = 0;
        for (size_t l = 0; l < power.size(); ++l) {
            if (!free[l]) continue;
            const double share = static_cast<double>(left) * rel[l] / sum;
            n[l] = static_cast<std::int64_t>(std::floor(share));
            assigned += n[l];
            rem.emplace_back(share - static_cast<double>(n[l]), l);
        }
        std::stable_sort(rem.begin(), rem.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
        for (size_t i = 0; assigned < left; i = (i + 1) % rem.size(), ++assigned) ++n[rem[i].second];
        break;
    }
    for (size_t l = 0; l < power.size(); ++l)
        if (power[l] > 0 && !free[l]) n[l] = batches;
    return n;
}

namespace {

// Mean and standard error of K batch estimates from their sum s and sum of squares s2 (one
// batch: no standard error, 0).
void batch_mean_stderr(double s, double s2, int K, double& mean, double& se) {
    const double k = std::max(1, K);
    mean = s / k;
    se = K > 1 ? std::sqrt(std::max(0.0, s2 / k - mean * mean) / (k - 1)) : 0.0;
}

// The per-cell sums of the replicated grid (this rank's share of the batches), reduced to the
// owner of each cell: only the tallied cells (with density, or all with empty_cells; every rank
// knows the replicated rho, `has_density` says which), packed by destination rank. `at(i, j, k)` is a cell's
// index into the sums ([cell][band]); quantities per band and cell: sum, sumsq (and rsum,
// rsumsq with the reduced tally). Fills res's per-band fields (mean and standard error of K
// batches), halo-exchanged. Collective.
template <class HasDensity, class At>
void reduce_to_owners(const Decomposition& d, int nb, int K, HasDensity&& has_density, At&& at,
                      const std::vector<double>& sum, const std::vector<double>& sumsq,
                      const std::vector<double>* rsum, const std::vector<double>* rsumsq,
                      const std::vector<double>* fsum, ForwardResult& res) {
    const int P = d.size(), nq = (rsum ? 4 : 2) + (fsum ? 3 : 0);
    std::vector<std::int64_t> recv_counts(static_cast<size_t>(P), 0);
    for (int r = 0; r < P; ++r)
        for_each_cell(d.box_of(r), [&](int i, int j, int k) {
            if (has_density(i, j, k)) recv_counts[static_cast<size_t>(r)] += nb * nq;
        });
    std::vector<double> send;
    send.reserve(static_cast<size_t>(std::accumulate(recv_counts.begin(), recv_counts.end(), std::int64_t{0})));
    for (int r = 0; r < P; ++r)
        for_each_cell(d.box_of(r), [&](int i, int j, int k) {
            if (!has_density(i, j, k)) return;
            const size_t c = static_cast<size_t>(at(i, j, k)) * nb;
            for (int q = 0; q < nb; ++q) {
                send.push_back(sum[c + q]);
                send.push_back(sumsq[c + q]);
                if (rsum) {
                    send.push_back((*rsum)[c + q]);
                    send.push_back((*rsumsq)[c + q]);
                }
                if (fsum)
                    for (int a = 0; a < 3; ++a) send.push_back((*fsum)[3 * (c + q) + a]);
            }
        });
    const std::vector<double> recv = reduce_scatter_sum(d.comm(), send, recv_counts);  // > 2^31: mpi_counts.h
    for (int q = 0; q < nb; ++q) {
        res.fluence.emplace_back(d.local(), 1, 1, 0.0);
        res.fluence_stderr.emplace_back(d.local(), 1, 1, 0.0);
        if (rsum) {
            res.reduced.emplace_back(d.local(), 1, 1, 0.0);
            res.reduced_stderr.emplace_back(d.local(), 1, 1, 0.0);
        }
        if (fsum) res.flux.emplace_back(d.local(), 1, 3, 0.0);
    }
    const double k_batches = std::max(1, K);
    size_t pos = 0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (!has_density(i, j, k)) return;
        for (int q = 0; q < nb; ++q) {
            batch_mean_stderr(recv[pos], recv[pos + 1], K, res.fluence[static_cast<size_t>(q)](i, j, k),
                              res.fluence_stderr[static_cast<size_t>(q)](i, j, k));
            pos += 2;
            if (rsum) {
                batch_mean_stderr(recv[pos], recv[pos + 1], K, res.reduced[static_cast<size_t>(q)](i, j, k),
                                  res.reduced_stderr[static_cast<size_t>(q)](i, j, k));
                pos += 2;
            }
            if (fsum)
                for (int a = 0; a < 3; ++a) res.flux[static_cast<size_t>(q)](i, j, k, a) = recv[pos++] / k_batches;
        }
    });
    for (auto* v : {&res.fluence, &res.fluence_stderr, &res.reduced, &res.reduced_stderr, &res.flux})
        for (Field<double>& f : *v) exchange_halo(f, d);
}

// Mean and standard error per band and counter of the K kept batches' counters (all_counters:
// [batch][band]). Two passes over the stored values: sum((v - mean)²) has no cancellation,
// unlike sum(v²)/K - mean², which turned round-off of the sums' order (a budget run's chunks)
// into 1e-11 differences of the standard error.
void counter_statistics(const std::vector<Counters>& all_counters, int nb, int K, ForwardResult& res) {
    res.counters.assign(static_cast<size_t>(nb), Counters{});
    res.counters_stderr.assign(static_cast<size_t>(nb), Counters{});
    for (int q = 0; q < nb; ++q)
        for (int c = 0; c < ncounters; ++c) {
            const auto value = [&](int b) { return all_counters[static_cast<size_t>(b) * nb + q][c]; };
            double m = 0.0, ss = 0.0;
            for (int b = 0; b < K; ++b) m += value(b);
            m /= std::max(1, K);
            for (int b = 0; b < K; ++b) ss += (value(b) - m) * (value(b) - m);
            res.counters[static_cast<size_t>(q)][c] = m;
            res.counters_stderr[static_cast<size_t>(q)][c] =
                K > 1 ? std::sqrt(ss / (static_cast<double>(K) * (K - 1))) : 0.0;
        }
}

}  // namespace

double relative_standard_error(double s1, double s2, int K) {
    double mean = 0.0, se = 0.0;
    batch_mean_stderr(s1, s2, K, mean, se);
    return mean > 0 ? se / mean : 0.0;
}

StopEta eta_to_stop(const MonteCarloOptions& opt, int done, double trace_seconds, double elapsed,
                    double rel_error) {
    const double per_batch = trace_seconds / std::max(1, done);
    StopEta eta{std::max(0, opt.batches - done) * per_batch, "photon count"};
    if (opt.time_budget > 0 && opt.time_budget - elapsed < eta.seconds)
        eta = {std::max(0.0, opt.time_budget - elapsed), "time budget"};
    if (opt.target_rel_error > 0 && rel_error > 0) {
        // The target is tested from kMinBatchesForTarget batches on (or all, if fewer): no
        // earlier stop (a QA run said "ETA 0.0 s" for batches 1 to 7).
        const double r = rel_error / opt.target_rel_error;
        const double needed = std::max(std::ceil(done * r * r), static_cast<double>(std::min(kMinBatchesForTarget, opt.batches)));
        const double left = std::max(0.0, needed - done) * per_batch;
        if (left < eta.seconds) eta = {left, "target error (estimated from 1/sqrt(batches))"};
    }
    return eta;
}

void check_replicated_memory(const std::array<int, 3>& n, double bytes, const MonteCarloOptions& opt) {
    if (bytes / 1e9 > opt.max_replicated_memory_gb)
        throw Error(fmt::format(
            "Monte Carlo replicates the {}x{}x{} grid on every rank: {:.3g} GB per rank exceeds "
            "model.montecarlo.max_replicated_memory_gb = {:.3g}; raise that limit, run fewer ranks "
            "per node, or use a coarser grid",
            n[0], n[1], n[2], bytes / 1e9, opt.max_replicated_memory_gb));
}

int batch_split(double batch_seconds, double seconds_left, int batches, int ranks,
                std::int64_t max_batches) {
    if (!(batch_seconds > 0)) return 1;
    const double left = std::max(0.0, seconds_left);
    const int rounds_all = (batches + ranks - 1) / ranks;
    auto rounds = [&](int split) { return std::floor(left * split / batch_seconds); };
    if (rounds(1) >= rounds_all || rounds(1) * ranks >= std::min(batches, kMinBudgetBatches))
        return 1;
    int split = 1;
    while (rounds(split) < rounds_all + 1 && batch_seconds / (2.0 * split) >= kMinBatchSeconds &&
           static_cast<std::int64_t>(batches) * split * 2 <= max_batches)
        split *= 2;
    return split;
}

void check_kernel(MPI_Comm comm, const MonteCarloOptions& opt) {
    check_collective(comm, opt.kernel != "lanes" || lane_kernel_supported(),
                     "model.montecarlo.kernel = \"lanes\" needs AVX-512 (x86-64-v4), which this CPU lacks: use "
                     "\"auto\" or \"scalar\"");
}

bool uses_lane_kernel(const MonteCarloOptions& opt, const ForwardSettings& settings) {
    if (settings.forced_first_collision || settings.tally_reduced || opt.kernel == "scalar") return false;
    return opt.kernel == "lanes" || lane_kernel_supported();
}

ForwardResult trace_forward(const Decomposition& d, const Medium& medium,
                            const std::vector<DirectionalLight>& lights,
                            const MonteCarloOptions& opt, const ForwardSettings& settings) {
    return trace_forward(d, medium, lights, {}, opt, settings);
}

ForwardResult trace_forward(const Decomposition& d, const Medium& medium,
                            const std::vector<DirectionalLight>& lights,
                            const std::vector<VolumeSource>& sources,
                            const MonteCarloOptions& opt, const ForwardSettings& settings) {
    opt.validate();
    check_kernel(d.comm(), opt);
    const double t_start = wall_time();
    const int nb = medium.nbands();
    ReplicatedProblem problem = replicate_problem(d, medium, lights, sources, opt, settings);
    ForwardResult res;
    res.replicated_gb = problem.replicated_gb;
    KeptBatches kept_sums(problem, settings);
    const bool lanes = uses_lane_kernel(opt, settings);
    BatchInFlight flight(problem, opt, settings, lanes, kept_sums);
    res.kernel = lanes ? "lanes" : "scalar";
    const double t_setup = wall_time();

    // The batch layout: batch b of term l is [b n_l / layout, (b+1) n_l / layout); layout is
    // opt.batches unless the time budget's pilot split the batches (batch_split), at most so far
    // that every batch keeps a photon of every term.
    int layout = opt.batches;
    std::int64_t max_layout = std::int64_t{1} << 30;
    for (const std::int64_t nl_photons : problem.n_light)
        if (nl_photons > 0) max_layout = std::min(max_layout, nl_photons);

    // Rounds: each rank traces one batch (ranks past the last batch idle). Without a time budget
    // a batch is traced in one piece. With one, in chunks of about chunk_seconds, and a rank
    // stops its batch at the budget's deadline (batches 0 and 1 always complete: a standard
    // error needs two); the round keeps its batches up to the first incomplete one, so the
    // result is always that of the first `done` batches of the layout, and a cut round ends the
    // run on every rank. In round 0 a pilot measures how long a batch takes and may split the
    // batches (batch_split; round 0 is then traced again). After each round rank 0 decides
    // whether the target error is reached and broadcasts it.
    const int P = d.size();
    const bool budget = opt.time_budget > 0;
    const bool any_light = std::any_of(problem.n_light.begin(), problem.n_light.end(), [](std::int64_t v) { return v > 0; });
    const std::int64_t steps = budget ? kChunkSteps : 1;
    const double chunk_seconds = std::min(kChunkSeconds, opt.time_budget / 50.0);
    const double pilot_seconds = std::min(kPilotSeconds, opt.time_budget / 32.0);
    double deadline = std::numeric_limits<double>::infinity();  // on this rank's clock
    if (budget) {
        // One clock for all ranks: the budget began when the earliest rank entered.
        const double mine = wall_time() - t_start;
        double earliest = 0.0;
        MPI_Allreduce(&mine, &earliest, 1, MPI_DOUBLE, MPI_MAX, d.comm());
        deadline = wall_time() + opt.time_budget - earliest;
    }
    // The pilot (collective, once, in round 0 of a budget run): the longest batch time over the
    // ranks, estimated from the fraction of its batch each traced in `seconds`.
    bool piloted = !budget;
    double pilot_batch_seconds = 0.0;
    auto pilot = [&](double fraction, double seconds) {
        piloted = true;
        const double mine[2] = {fraction > 0 ? seconds / fraction : 0.0, wall_time() - t_start};
        double most[2] = {0.0, 0.0};
        MPI_Allreduce(mine, most, 2, MPI_DOUBLE, MPI_MAX, d.comm());
        pilot_batch_seconds = most[0];
        return batch_split(most[0], opt.time_budget - most[1], layout, P, max_layout);
    };
    Progress progress("montecarlo", static_cast<double>(opt.photons), d.rank() == 0);
    const double t_progress = wall_time();  // what the progress line counts as elapsed
    std::vector<Counters> all_counters;  // [batch][band], of the batches kept, summed over ranks
    std::vector<double> round_sums;      // a round's counters and flags, summed over the ranks
    const size_t per_batch = static_cast<size_t>(nb) * ncounters;
    double diffuse_s1 = 0.0, diffuse_s2 = 0.0;  // sum, sum of squares of each batch's diffuse power
    int done = 0;                               // batches kept (of this layout)
    double t_layout = t_setup;                  // when tracing in this layout began
    std::int64_t dk = 1;                        // chunk width in steps, adapted to chunk_seconds
    res.stop_reason = any_light ? "photons" : "no light";
    while (any_light && done < layout) {
        const int cnt = std::min(layout - done, P);
        const int batch = d.rank() < cnt ? done + d.rank() : -1;  // this rank's batch, or none
        const double t_round = wall_time();
        std::int64_t k = 0;
        int split = 1;
        while (batch >= 0 && k < steps) {
            const std::int64_t k1 = std::min(steps, k + (budget ? dk : steps));
            const double t0 = wall_time();
            flight.trace(batch, layout, k, k1, steps);
            k = k1;
            if (!budget) continue;
            const double now = wall_time();
            if (now - t0 < 0.5 * chunk_seconds)
                dk = std::min(steps, 2 * dk);
            else if (now - t0 > 2.0 * chunk_seconds)
                dk = std::max<std::int64_t>(1, dk / 2);
            if (!piloted && now - t_round >= pilot_seconds) {
                split = pilot(static_cast<double>(k) / static_cast<double>(steps), now - t_round);
                if (split > 1) break;
            }
            if (batch >= 2 && k < steps && now >= deadline) break;
        }
        if (!piloted)
            split = pilot(batch >= 0 ? static_cast<double>(k) / static_cast<double>(steps) : 0.0,
                          wall_time() - t_round);
        if (split > 1) {
            flight.end(false);
            log::info(
                "montecarlo: a batch of {} photons would take {:.2f} s of the {:.2f} s time "
                "budget: {} batches of {} photons instead",
                opt.photons / layout, pilot_batch_seconds, opt.time_budget, layout * split,
                opt.photons / (static_cast<std::int64_t>(layout) * split));
            layout *= split;
            dk = std::min(steps, dk * split);
            t_layout = wall_time();
            continue;
        }
        // The round's counters, which of its batches are complete, and whether any rank's clock
        // has passed the deadline, summed over the ranks (each batch's values come from the one
        // rank that traced it).
        round_sums.assign(static_cast<size_t>(cnt) * (per_batch + 1) + 1, 0.0);
        double* counters_of = round_sums.data();  // [batch in round][band][counter]
        double* complete = counters_of + static_cast<size_t>(cnt) * per_batch;  // [batch in round]
        double& expired = round_sums.back();
        expired = wall_time() >= deadline ? 1.0 : 0.0;
        if (batch >= 0) {
            for (int q = 0; q < nb; ++q)
                std::copy_n(
                    flight.counters()[static_cast<size_t>(q)].begin(), ncounters,
                    counters_of + static_cast<size_t>(batch - done) * per_batch + q * ncounters);
            complete[batch - done] = k == steps ? 1.0 : 0.0;
        }
        MPI_Allreduce(MPI_IN_PLACE, round_sums.data(), static_cast<int>(round_sums.size()),
                      MPI_DOUBLE, MPI_SUM, d.comm());
        int kept = 0;
        while (kept < cnt && complete[kept] > 0) ++kept;
        // The total diffuse power of each complete batch (its counters summed over bands).
        std::vector<double> power_of(static_cast<size_t>(kept), 0.0);
        for (int b = 0; b < kept; ++b)
            for (int q = 0; q < nb; ++q)
                power_of[static_cast<size_t>(b)] +=
                    counters_of[static_cast<size_t>(b) * per_batch + q * ncounters + diffuse_volume];
        // target_rel_error: the run keeps the first K batches of the layout, K the smallest batch
        // count from kMinBatchesForTarget on whose relative error is below the target; tested
        // batch by batch, so K (and the result) does not depend on how many batches a round has,
        // i.e. on the rank count. Rank 0 decides (the counters are the same on every rank).
        int target_kept = 0;
        if (opt.target_rel_error > 0 && d.rank() == 0) {
            double s1 = diffuse_s1, s2 = diffuse_s2;
            for (int b = 0; b < kept && target_kept == 0; ++b) {
                const double v = power_of[static_cast<size_t>(b)];
                s1 += v, s2 += v * v;
                const int K = done + b + 1;
                // s1 > 0: batches that tallied no diffuse power at all estimate no error (the
                // function's 0 would meet any target after a few empty batches).
                if (K >= std::min(kMinBatchesForTarget, layout) && K < layout && s1 > 0 &&
                    relative_standard_error(s1, s2, K) < opt.target_rel_error)
                    target_kept = b + 1;
            }
        }
        MPI_Bcast(&target_kept, 1, MPI_INT, 0, d.comm());
        if (target_kept > 0) kept = target_kept;
        if (batch >= 0) flight.end(batch < done + kept);
        for (int b = 0; b < kept; ++b) {
            for (int q = 0; q < nb; ++q) {
                Counters c;
                std::copy_n(counters_of + static_cast<size_t>(b) * per_batch + q * ncounters,
                            ncounters, c.begin());
                all_counters.push_back(c);
            }
            const double v = power_of[static_cast<size_t>(b)];
            diffuse_s1 += v;
            diffuse_s2 += v * v;
        }
        done += kept;
        log::debug("montecarlo: round done: {} of {} batches kept ({} complete this round)", done, layout, kept);
        res.rel_error = diffuse_s1 > 0 ? relative_standard_error(diffuse_s1, diffuse_s2, done)
                                       : std::numeric_limits<double>::quiet_NaN();  // nothing tallied
        if (target_kept > 0) {
            res.stop_reason = "target_rel_error";
            break;
        }
        // The deadline cut a batch, or passed while the round's batches completed (every rank
        // sees the same flags); the first two batches are traced in any case.
        if (kept < cnt || (expired > 0 && done >= 2 && done < layout)) {
            res.stop_reason = "time_budget";
            break;
        }
        if (d.rank() == 0) {
            const double now = wall_time();
            MonteCarloOptions in_layout = opt;
            in_layout.batches = layout;
            const StopEta eta =
                eta_to_stop(in_layout, done, now - t_layout, now - t_start, res.rel_error);
            // The share of the way to the earliest stop: of the batches when the photon count
            // stops the run, else of the time to the budget or the target's projected stop (a
            // QA finding: "1.2% (4.3 s elapsed, ETA 1.7 s at the time budget)").
            const double elapsed = now - t_progress;
            const double share = eta.until != "photon count" && std::isfinite(eta.seconds) && elapsed + eta.seconds > 0
                                     ? elapsed / (elapsed + eta.seconds)
                                     : static_cast<double>(done) / layout;
            progress.update(static_cast<double>(opt.photons) * share, eta.seconds, eta.until);
        }
    }
    progress.finish();
    if (done > 0 && done < kMinBatchesForTarget && d.rank() == 0)  // 0: no light, nothing traced
        log::warn("montecarlo: the standard errors come from {} batch means only ({} degrees of freedom) and "
                  "are themselves uncertain; use more batches (model.montecarlo.batches) or a longer time_budget",
                  done, std::max(0, done - 1));
    const double t_traced = wall_time();
    res.batches = done;
    res.layout_batches = layout;
    std::int64_t counts[3] = {kept_sums.photons, kept_sums.collisions, kept_sums.segments}, total[3] = {0, 0, 0};
    MPI_Allreduce(counts, total, 3, MPI_INT64_T, MPI_SUM, d.comm());
    res.photons = total[0];
    res.collisions = total[1];
    res.segments = total[2];

    counter_statistics(all_counters, nb, done, res);
    reduce_to_owners(
        d, nb, done, [&](int i, int j, int k) { return problem.tallied(i, j, k); },
        [&](int i, int j, int k) { return problem.box_index(i, j, k); }, kept_sums.sum, kept_sums.sumsq,
        settings.tally_reduced ? &kept_sums.rsum : nullptr, settings.tally_reduced ? &kept_sums.rsumsq : nullptr,
        settings.tally_flux ? &kept_sums.fsum : nullptr, res);
    // Phase times, the maximum over the ranks (so that every rank reports the same values).
    const double t_end = wall_time();
    double times[4] = {t_end - t_start, t_setup - t_start, t_traced - t_setup, t_end - t_traced}, tmax[4];
    MPI_Allreduce(times, tmax, 4, MPI_DOUBLE, MPI_MAX, d.comm());
    res.seconds = tmax[0];
    res.setup_seconds = tmax[1];
    res.trace_seconds = tmax[2];
    res.reduce_seconds = tmax[3];
    return res;
}

}  // namespace nimbus::mc
