#include "solvers/montecarlo/forward.h"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include "solvers/montecarlo/emitter.h"
#include "src/core/empty_space.h"
#include "src/core/grid_walk.h"
#include "solvers/montecarlo/photon.h"
#include "solvers/montecarlo/trace_light.h"
#include "src/core/error.h"
#include "src/core/gather.h"
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
// owner of each cell: only cells with density (the others are never tallied; every rank knows
// the replicated rho, `has_density`), packed by destination rank. `at(i, j, k)` is a cell's
// index into the sums ([cell][band]); quantities per band and cell: sum, sumsq (and rsum,
// rsumsq with the reduced tally). Fills res's per-band fields (mean and standard error of K
// batches), halo-exchanged. Collective.
template <class HasDensity, class At>
void reduce_to_owners(const Decomposition& d, int nb, int K, HasDensity&& has_density, At&& at,
                      const std::vector<double>& sum, const std::vector<double>& sumsq,
                      const std::vector<double>* rsum, const std::vector<double>* rsumsq, ForwardResult& res) {
    const int P = d.size(), nq = rsum ? 4 : 2;
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
    }
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
        }
    });
    for (auto* v : {&res.fluence, &res.fluence_stderr, &res.reduced, &res.reduced_stderr})
        for (Field<double>& f : *v) exchange_halo(f, d);
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
        const double r = rel_error / opt.target_rel_error;
        const double left = std::max(0.0, std::ceil(done * r * r) - done) * per_batch;
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
    const double t_start = wall_time();
    const Int3 n = d.global().hi;
    const std::int64_t cells = d.global().cells();
    const int nb = medium.nbands();
    const int B = opt.batches;
    const double h = medium.grid.h;
    const std::vector<OpticsGroup> groups = group_by_optics(medium.bands);  // traced once per group
    for (const OpticsGroup& g : groups)
        if (g.bands.size() > 64) throw Error("Monte Carlo supports at most 64 bands with equal optics");

    // Memory of the replicated arrays, per rank (replicated_bytes, forward.h).
    double source_cells = 0.0;
    for (const VolumeSource& src : sources) source_cells += static_cast<double>(src.cells.cells());
    const double bytes = replicated_bytes(static_cast<double>(cells), static_cast<int>(groups.size()), nb,
                                          settings.tally_reduced, source_cells);
    ForwardResult res;
    res.replicated_gb = bytes / 1e9;
    check_replicated_memory(n, bytes, opt);

    const std::vector<double> rho = allgather_global(medium.rho, d);
    std::array<bool, 3> periodic{d.periodic(0), d.periodic(1), d.periodic(2)};

    // Bounding box of the non-empty cells (the whole extent along periodic axes).
    Int3 box_lo = n, box_hi{0, 0, 0};
    for_each_cell(d.global(), [&](int i, int j, int k) {
        if (rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] > 0) {
            const Int3 c{i, j, k};
            for (int a = 0; a < 3; ++a) box_lo[a] = std::min(box_lo[a], c[a]), box_hi[a] = std::max(box_hi[a], c[a] + 1);
        }
    });
    for (int a = 0; a < 3; ++a)
        if (periodic[a] || box_hi[a] <= box_lo[a]) box_lo[a] = 0, box_hi[a] = periodic[a] ? n[a] : 0;

    // The walk's grid covers only the box (outside it all is empty), padded by one ghost
    // layer (grid_walk.h); the per-cell arrays below use the walk's cell indices.
    Int3 box_n;
    for (int a = 0; a < 3; ++a) box_n[a] = std::max(box_hi[a] - box_lo[a], 1);
    const GridView padded{box_n, periodic, nullptr};
    const std::int64_t pcells = static_cast<std::int64_t>(box_n[0] + 2) * (box_n[1] + 2) * (box_n[2] + 2);
    auto box_index = [&](int i, int j, int k) { return padded.index({i - box_lo[0], j - box_lo[1], k - box_lo[2]}); };

    // Light terms: entry faces, projected area (m²) of the domain and of the box's live pixels
    // (photon.h: rays through the rest meet only empty cells), photon counts.
    std::vector<EntrySampler> entry;
    std::vector<double> area, domain_area, power;
    const std::vector<Int3> surface = surface_cells(
        {box_hi[0] - box_lo[0], box_hi[1] - box_lo[1], box_hi[2] - box_lo[2]}, periodic, [&](const Int3& c) {
            return rho[(static_cast<size_t>(c[2] + box_lo[2]) * n[1] + (c[1] + box_lo[1])) * n[0] + (c[0] + box_lo[0])] > 0;
        });
    for (const DirectionalLight& L : lights) {
        domain_area.push_back(EntrySampler({0, 0, 0}, n, periodic, L.w).projected_area * h * h);
        entry.emplace_back(box_lo, box_hi, periodic, L.w);
        entry.back().restrict_to(surface, periodic, L.w);
        area.push_back(entry.back().projected_area * h * h);
        double p = 0.0;
        for (int b = 0; b < nb; ++b) p += L.E0[static_cast<size_t>(b)] * area.back();
        power.push_back(p);
    }
    // Volume sources: the emitting cells of each, then its power, after the lights' (one
    // budget, photons_per_light).
    std::vector<VolumeEmitter> emitters;
    for (const VolumeSource& src : sources) {
        emitters.emplace_back(src.power, src.cells, [&](int i, int j, int k) {
            return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i];
        }, h);
        double p = 0.0;
        for (int b = 0; b < nb; ++b) p += emitters.back().total_power(b);
        power.push_back(p);
    }
    // A power that overflows (e.g. irradiance x area beyond 1.8e308 W) would make every share
    // NaN; every rank has the same powers, so every rank throws alike.
    for (size_t t = 0; t < power.size(); ++t)
        if (!std::isfinite(power[t]))
            throw Error(fmt::format("montecarlo: the power of {} is not finite ({} W summed over bands): the "
                                    "irradiance, radiance or source power times the area or volume overflows; "
                                    "use smaller values or units",
                                    t < lights.size() ? fmt::format("light term {} ('{}')", t, lights[t].name)
                                                      : fmt::format("sources[{}]", t - lights.size()),
                                    power[t]));
    const std::vector<std::int64_t> n_light = photons_per_light(power, opt.photons, B);
    const std::int64_t n_total = std::accumulate(n_light.begin(), n_light.end(), std::int64_t{0});
    if (n_total > opt.photons)
        log::warn("montecarlo: {} photons asked for, {} traced: every lit term takes at least one photon per "
                  "batch ({} terms, {} batches)",
                  opt.photons, n_total, std::count_if(power.begin(), power.end(), [](double p) { return p > 0; }), B);
    const size_t nl = lights.size(), nt = nl + emitters.size();  // light terms, all terms

    // Per-rank accumulators over the global grid: [cell][band] sum and sum of squares of the
    // batch estimates (and of the reduced tally).
    std::vector<double> sum(static_cast<size_t>(pcells * nb), 0.0), sumsq(sum.size(), 0.0);
    std::vector<double> rsum, rsumsq;
    if (settings.tally_reduced) rsum.assign(sum.size(), 0.0), rsumsq.assign(sum.size(), 0.0);
    std::int64_t my_photons = 0, my_collisions = 0, my_segments = 0;  // of the batches kept

    std::vector<VoxelGrid> voxels(groups.size());
    {
        std::vector<float> kappa(static_cast<size_t>(box_n[0]) * box_n[1] * box_n[2], 0.0f);
        for (size_t gi = 0; gi < groups.size(); ++gi) {
            for (int k = box_lo[2]; k < box_hi[2]; ++k)
                for (int j = box_lo[1]; j < box_hi[1]; ++j)
                    for (int i = box_lo[0]; i < box_hi[0]; ++i)
                        kappa[(static_cast<size_t>(k - box_lo[2]) * box_n[1] + (j - box_lo[1])) * box_n[0] + (i - box_lo[0])] =
                            static_cast<float>(rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] * groups[gi].optics.sigma_t * h);
            voxels[gi] = make_voxels(box_n, kappa);
            voxels[gi].origin = box_lo;
            voxels[gi].domain = n;
        }
    }
    // The tally of the batch in flight, [cell][band], reused across batches: only the cells a
    // batch touched are folded into the sums (or zeroed, for a batch the time budget cut), so a
    // batch costs O(cells touched), not O(grid). A cell is listed when its tally of the light's
    // strongest band is still 0 (every tallied segment adds a positive amount there; a repeated
    // entry folds 0, harmlessly).
    std::vector<double> tally(static_cast<size_t>(pcells) * nb, 0.0), rtally, reduced_acc;
    if (settings.tally_reduced) rtally.assign(tally.size(), 0.0), reduced_acc.assign(static_cast<size_t>(pcells), 0.0);
    std::vector<std::int64_t> touched, light_touched;  // cells tallied in this batch / by this light
    light_touched.reserve(static_cast<size_t>(std::min<std::int64_t>(cells, 1 << 20)));
    touched.reserve(static_cast<size_t>(std::min<std::int64_t>(cells, 1 << 20)));
    // The rest of the batch in flight: its energy counters per band and its photon, collision
    // and segment counts, kept apart until the round knows whether the batch is kept.
    std::vector<Counters> flight(static_cast<size_t>(nb), Counters{});
    std::int64_t flight_photons = 0, flight_collisions = 0, flight_segments = 0;
    const double t_setup = wall_time();

    // The batch layout: batch b of term l is [b n_l / layout, (b+1) n_l / layout); layout is
    // opt.batches unless the time budget's pilot split the batches (batch_split), at most so far
    // that every batch keeps a photon of every term.
    int layout = B;
    std::int64_t max_layout = std::int64_t{1} << 30;
    for (const std::int64_t nl_photons : n_light)
        if (nl_photons > 0) max_layout = std::min(max_layout, nl_photons);

    // Traces part [k0, k1) of the kChunkSteps steps of `batch` (of every term the photons
    // [lo + (hi - lo) k0 / S, lo + (hi - lo) k1 / S); k0 = 0, k1 = S is the whole batch) into the
    // batch in flight.
    auto trace_chunk = [&](int batch, std::int64_t k0, std::int64_t k1, std::int64_t steps) {
        auto offset = [steps](std::int64_t count, std::int64_t k) {  // count k / steps, exactly
            return count / steps * k + count % steps * k / steps;
        };
        for (size_t gi = 0; gi < groups.size(); ++gi) {
            const OpticsGroup& G = groups[gi];
            const int nbg = static_cast<int>(G.bands.size());
            const int* band = G.bands.data();
            const GridView grid = voxels[gi].view(periodic);
            const PhotonOptics po{G.optics.albedo, G.optics.g, opt.roulette_weight};
            for (size_t l = 0; l < nt; ++l) {
                if (n_light[l] == 0) continue;
                const VolumeEmitter* emitter = l < nl ? nullptr : &emitters[l - nl];
                const std::int64_t lo = batch * n_light[l] / layout,
                                   hi = (batch + 1) * n_light[l] / layout;
                if (hi <= lo) continue;
                const std::int64_t from = lo + offset(hi - lo, k0), to = lo + offset(hi - lo, k1);
                // Photon power per band (W) in this batch's estimate, and the fluence scale
                // P len(m) / V = P len(cells) / h².
                double P[64]{}, scale[64]{};
                int strongest = 0;
                for (int q = 0; q < nbg; ++q) {
                    P[q] = (emitter ? emitter->total_power(band[q])
                                    : lights[l].E0[static_cast<size_t>(band[q])] * area[l]) /
                           static_cast<double>(hi - lo);
                    scale[q] = P[q] / (h * h);
                    if (scale[q] > scale[strongest]) strongest = q;
                }
                if (!(scale[strongest] > 0)) {  // no power in this group's bands (nothing to tally)
                    if (gi == 0) flight_photons += to - from;
                    continue;
                }
                if (k0 == 0)  // once per batch: the term's power, and the rays that miss the box
                    for (int q = 0; q < nbg; ++q) {
                        Counters& c = flight[static_cast<size_t>(band[q])];
                        if (emitter) {
                            c[emitted] += emitter->total_power(band[q]);
                        } else {
                            const double E0 = lights[l].E0[static_cast<size_t>(band[q])];
                            c[incident] += E0 * domain_area[l];
                            c[escaped_direct] += E0 * (domain_area[l] - area[l]);
                        }
                    }
                if (to <= from) continue;
                // Trace (trace_light.h: w len accumulated per voxel), then fold the light's
                // accumulators into the per-band batch tally (x P/h² per band) and zero them.
                PathTally pt;
                light_touched.clear();
                const LightTerm term{emitter ? nullptr : &entry[l], emitter ? Vec3{0, 0, -1} : lights[l].w, emitter,
                                     static_cast<std::uint32_t>(l)};
                trace_photons(grid, po, term, opt.seed, from, to, settings.forced_first_collision,
                              settings.tally_reduced ? reduced_acc.data() : nullptr, light_touched,
                              pt);
                auto fold = [&](std::vector<double>& to_tally, std::int64_t idx, double track) {
                    double* c = to_tally.data() + idx * nb;
                    if (c[band[strongest]] == 0.0) touched.push_back(idx);
                    for (int q = 0; q < nbg; ++q) c[band[q]] += track * scale[q];
                };
                double diffuse_track = 0.0;  // sum of w len (cells) after the first scattering
                for (const std::int64_t idx : light_touched) {
                    const double v = std::exchange(grid.voxel[idx].tally, 0.0);
                    diffuse_track += v;
                    if (v != 0.0) fold(tally, idx, v);
                    if (settings.tally_reduced) {
                        const double r = std::exchange(reduced_acc[static_cast<size_t>(idx)], 0.0);
                        if (r != 0.0) fold(rtally, idx, r);
                    }
                }
                if (gi == 0) flight_photons += to - from;  // a photon traced once per optics group
                flight_collisions += pt.collisions;
                flight_segments += pt.segments;
                for (int q = 0; q < nbg; ++q) {
                    Counters& c = flight[static_cast<size_t>(band[q])];
                    c[absorbed] += P[q] * pt.absorbed;
                    c[escaped_direct] += P[q] * pt.escaped_direct;
                    for (int f = 0; f < 6; ++f) c[escaped_xlo + f] += P[q] * pt.escaped_diffuse[f];
                    c[roulette_net] += P[q] * pt.roulette_net;
                    c[diffuse_volume] += P[q] * diffuse_track * h;
                }
            }
        }
    };
    // Ends the batch in flight: folds it into the sums and counts (keep) or drops it.
    auto end_batch = [&](bool keep) {
        auto fold = [&](std::vector<double>& from, std::vector<double>& s1, std::vector<double>& s2,
                        std::int64_t c) {
            double* v = from.data() + c * nb;
            for (int q = 0; q < nb; ++q) {
                if (keep) {
                    s1[static_cast<size_t>(c * nb + q)] += v[q];
                    s2[static_cast<size_t>(c * nb + q)] += v[q] * v[q];
                }
                v[q] = 0.0;
            }
        };
        for (const std::int64_t c : touched) {
            fold(tally, sum, sumsq, c);
            if (settings.tally_reduced) fold(rtally, rsum, rsumsq, c);
        }
        touched.clear();
        if (keep) {
            my_photons += flight_photons;
            my_collisions += flight_collisions;
            my_segments += flight_segments;
        }
        flight_photons = flight_collisions = flight_segments = 0;
        std::fill(flight.begin(), flight.end(), Counters{});
    };

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
    const bool any_light = std::any_of(n_light.begin(), n_light.end(), [](std::int64_t v) { return v > 0; });
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
            trace_chunk(batch, k, k1, steps);
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
            end_batch(false);
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
                    flight[static_cast<size_t>(q)].begin(), ncounters,
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
                if (K >= std::min(kMinBatchesForTarget, layout) && K < layout &&
                    relative_standard_error(s1, s2, K) < opt.target_rel_error)
                    target_kept = b + 1;
            }
        }
        MPI_Bcast(&target_kept, 1, MPI_INT, 0, d.comm());
        if (target_kept > 0) kept = target_kept;
        if (batch >= 0) end_batch(batch < done + kept);
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
        res.rel_error = relative_standard_error(diffuse_s1, diffuse_s2, done);
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
            progress.update(static_cast<double>(opt.photons) * done / layout, eta.seconds,
                            eta.until);
        }
    }
    progress.finish();
    if (done < kMinBatchesForTarget && d.rank() == 0)
        log::warn("montecarlo: the standard errors come from {} batch means only ({} degrees of freedom) and "
                  "are themselves uncertain; use more batches (model.montecarlo.batches) or a longer time_budget",
                  done, std::max(0, done - 1));
    const double t_traced = wall_time();
    res.batches = done;
    res.layout_batches = layout;
    std::int64_t counts[3] = {my_photons, my_collisions, my_segments}, total[3] = {0, 0, 0};
    MPI_Allreduce(counts, total, 3, MPI_INT64_T, MPI_SUM, d.comm());
    res.photons = total[0];
    res.collisions = total[1];
    res.segments = total[2];

    // Counters: mean and standard error of the batch estimates.
    res.counters.assign(static_cast<size_t>(nb), Counters{});
    res.counters_stderr.assign(static_cast<size_t>(nb), Counters{});
    // Two passes over the kept batches' values (all stored): sum((v - mean)²) has no cancellation,
    // unlike sum(v²)/K - mean², which turned round-off of the sums' order (a budget run's chunks)
    // into 1e-11 differences of the standard error.
    for (int q = 0; q < nb; ++q)
        for (int c = 0; c < ncounters; ++c) {
            const auto value = [&](int b) { return all_counters[static_cast<size_t>(b) * nb + q][c]; };
            double m = 0.0, ss = 0.0;
            for (int b = 0; b < done; ++b) m += value(b);
            m /= std::max(1, done);
            for (int b = 0; b < done; ++b) ss += (value(b) - m) * (value(b) - m);
            res.counters[static_cast<size_t>(q)][c] = m;
            res.counters_stderr[static_cast<size_t>(q)][c] =
                done > 1 ? std::sqrt(ss / (static_cast<double>(done) * (done - 1))) : 0.0;
        }
    reduce_to_owners(
        d, nb, done, [&](int i, int j, int k) { return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] > 0; },
        box_index, sum, sumsq, settings.tally_reduced ? &rsum : nullptr, settings.tally_reduced ? &rsumsq : nullptr,
        res);
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
