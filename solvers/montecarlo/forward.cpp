#include "solvers/montecarlo/forward.h"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
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
#include "src/core/progress.h"
#include "src/core/report.h"
#include "src/scene/optics_groups.h"

namespace nimbus::mc {

std::vector<std::int64_t> photons_per_light(const std::vector<double>& power, std::int64_t total,
                                            int batches) {
    std::vector<std::int64_t> n(power.size(), 0);
    std::vector<bool> free(power.size(), false);  // not (yet) held at the minimum
    for (size_t l = 0; l < power.size(); ++l) free[l] = power[l] > 0;
    // Lights whose share falls below the minimum get exactly `batches`; the rest share what is
    // left in proportion to their power (repeat until no share falls below the minimum).
    for (;;) {
        double sum = 0.0;
        std::int64_t left = total;
        for (size_t l = 0; l < power.size(); ++l) {
            if (free[l]) sum += power[l];
            else if (power[l] > 0) left -= batches;
        }
        if (sum <= 0) break;
        bool changed = false;
        for (size_t l = 0; l < power.size(); ++l)
            if (free[l] && static_cast<double>(left) * power[l] / sum < batches) free[l] = false, changed = true;
        if (changed) continue;
        // Largest remainder: floor of each share, the leftover photons one each to the largest
        // fractional parts (ties to the lower index), so the counts sum to `total` exactly.
        std::vector<std::pair<double, size_t>> rem;
        std::int64_t assigned = 0;
        for (size_t l = 0; l < power.size(); ++l) {
            if (!free[l]) continue;
            const double share = static_cast<double>(left) * power[l] / sum;
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
    const int nq = settings.tally_reduced ? 4 : 2;  // per band: sum, sumsq (+ reduced sum, sumsq)
    for (const OpticsGroup& g : groups)
        if (g.bands.size() > 64) throw Error("Monte Carlo supports at most 64 bands with equal optics");

    // Memory of the replicated arrays, per rank: density (gathered + global), the 16-byte voxels
    // (kappa, empty-space distance, light accumulator) per group,
    // per band the batch tally and its running sum and sum of squares, and the reduce buffer;
    // the emitting-cell lists of the volume sources (at most 4 bytes per covered cell).
    double source_cells = 0.0;
    for (const VolumeSource& src : sources) source_cells += static_cast<double>(src.cells.cells());
    const double bytes = static_cast<double>(cells) *
                         (16.0 + 16.0 * static_cast<double>(groups.size()) + 8.0 * nb * (nq / 2) * 3 + 8.0 * nb * nq + 12.0) +
                         4.0 * source_cells;
    ForwardResult res;
    res.replicated_gb = bytes / 1e9;
    if (res.replicated_gb > opt.max_replicated_memory_gb)
        throw Error(fmt::format(
            "Monte Carlo replicates the {}x{}x{} grid on every rank: {:.2f} GB per rank exceeds "
            "model.montecarlo.max_replicated_memory_gb = {:.2f}; raise that limit, run fewer ranks "
            "per node, or use a coarser grid",
            n[0], n[1], n[2], res.replicated_gb, opt.max_replicated_memory_gb));

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
    const std::vector<std::int64_t> n_light = photons_per_light(power, opt.photons, B);
    const size_t nl = lights.size(), nt = nl + emitters.size();  // light terms, all terms

    // Per-rank accumulators over the global grid: [cell][band] sum and sum of squares of the
    // batch estimates (and of the reduced tally).
    std::vector<double> sum(static_cast<size_t>(pcells * nb), 0.0), sumsq(sum.size(), 0.0);
    std::vector<double> rsum, rsumsq;
    if (settings.tally_reduced) rsum.assign(sum.size(), 0.0), rsumsq.assign(sum.size(), 0.0);
    std::vector<Counters> batch_counters(static_cast<size_t>(B) * nb, Counters{});  // [batch][band]
    std::int64_t my_photons = 0, my_collisions = 0, my_segments = 0;

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
    // Batch tallies, [cell][band in group], reused across batches: only the cells a batch
    // touched are folded into the sums and zeroed again, so a batch costs O(cells touched),
    // not O(grid). A cell is listed when its tally of the light's strongest band is still 0
    // (every tallied segment adds a positive amount there; a repeated entry folds 0, harmlessly).
    size_t max_group = 1;
    for (const OpticsGroup& G : groups) max_group = std::max(max_group, G.bands.size());
    std::vector<double> tally(static_cast<size_t>(pcells) * max_group, 0.0), rtally, reduced_acc;
    if (settings.tally_reduced) rtally.assign(tally.size(), 0.0), reduced_acc.assign(static_cast<size_t>(pcells), 0.0);
    std::vector<std::int64_t> touched, light_touched;  // cells tallied in this batch / by this light
    light_touched.reserve(static_cast<size_t>(std::min<std::int64_t>(cells, 1 << 20)));
    touched.reserve(static_cast<size_t>(std::min<std::int64_t>(cells, 1 << 20)));
    const double t_setup = wall_time();

    auto run_batch = [&](int batch) {
        for (size_t gi = 0; gi < groups.size(); ++gi) {
            const OpticsGroup& G = groups[gi];
            const int nbg = static_cast<int>(G.bands.size());
            touched.clear();
            const GridView grid = voxels[gi].view(periodic);
            const PhotonOptics po{G.optics.albedo, G.optics.g, opt.roulette_weight};
            for (size_t l = 0; l < nt; ++l) {
                if (n_light[l] == 0) continue;
                const VolumeEmitter* emitter = l < nl ? nullptr : &emitters[l - nl];
                const std::int64_t lo = batch * n_light[l] / B, hi = (batch + 1) * n_light[l] / B;
                if (hi <= lo) continue;
                // Photon power per band (W) in this batch's estimate, and the fluence scale
                // P len(m) / V = P len(cells) / h².
                double P[64]{}, scale[64]{};
                int strongest = 0;
                for (int q = 0; q < nbg; ++q) {
                    const int band = G.bands[static_cast<size_t>(q)];
                    P[q] = (emitter ? emitter->total_power(band) : lights[l].E0[static_cast<size_t>(band)] * area[l]) /
                           static_cast<double>(hi - lo);
                    scale[q] = P[q] / (h * h);
                    if (scale[q] > scale[strongest]) strongest = q;
                }
                if (!(scale[strongest] > 0)) {  // no power in this group's bands (nothing to tally)
                    if (gi == 0) my_photons += hi - lo;
                    continue;
                }
                // Trace (trace_light.h: w len accumulated per voxel), then fold the light's
                // accumulators into the per-band batch tally (x P/h² per band) and zero them.
                PathTally pt;
                light_touched.clear();
                const LightTerm term{emitter ? nullptr : &entry[l], emitter ? Vec3{0, 0, -1} : lights[l].w, emitter,
                                     static_cast<std::uint32_t>(l)};
                trace_photons(grid, po, term, opt.seed, lo, hi, settings.forced_first_collision,
                              settings.tally_reduced ? reduced_acc.data() : nullptr, light_touched, pt);
                auto fold = [&](std::vector<double>& to, std::int64_t idx, double track) {
                    double* c = to.data() + idx * nbg;
                    if (c[strongest] == 0.0) touched.push_back(idx);
                    for (int q = 0; q < nbg; ++q) c[q] += track * scale[q];
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
                if (gi == 0) my_photons += hi - lo;  // a photon traced once per optics group
                my_collisions += pt.collisions;
                my_segments += pt.segments;
                for (int q = 0; q < nbg; ++q) {
                    Counters& c = batch_counters[static_cast<size_t>(batch) * nb + G.bands[static_cast<size_t>(q)]];
                    if (emitter) {
                        c[emitted] += emitter->total_power(G.bands[static_cast<size_t>(q)]);
                    } else {
                        const double E0 = lights[l].E0[static_cast<size_t>(G.bands[static_cast<size_t>(q)])];
                        c[incident] += E0 * domain_area[l];
                        c[escaped_direct] += E0 * (domain_area[l] - area[l]);  // rays missing the box
                    }
                    c[absorbed] += P[q] * pt.absorbed;
                    c[escaped_direct] += P[q] * pt.escaped_direct;
                    for (int f = 0; f < 6; ++f) c[escaped_xlo + f] += P[q] * pt.escaped_diffuse[f];
                    c[roulette_net] += P[q] * pt.roulette_net;
                    c[diffuse_volume] += P[q] * diffuse_track * h;
                }
            }
            const int* band = G.bands.data();
            for (const std::int64_t c : touched) {
                double* src = tally.data() + c * nbg;
                double* s1 = sum.data() + c * nb;
                double* s2 = sumsq.data() + c * nb;
                for (int q = 0; q < nbg; ++q) {
                    const double v = src[q];
                    s1[band[q]] += v;
                    s2[band[q]] += v * v;
                    src[q] = 0.0;
                }
                if (settings.tally_reduced) {
                    double* rsrc = rtally.data() + c * nbg;
                    double* r1 = rsum.data() + c * nb;
                    double* r2 = rsumsq.data() + c * nb;
                    for (int q = 0; q < nbg; ++q) {
                        const double r = rsrc[q];
                        r1[band[q]] += r;
                        r2[band[q]] += r * r;
                        rsrc[q] = 0.0;
                    }
                }
            }
        }
    };

    // Rounds of batches; stop criteria decided on rank 0 and broadcast.
    const int P = d.size();
    const int round_size = std::max(2, P);
    const bool any_light = std::any_of(n_light.begin(), n_light.end(), [](std::int64_t v) { return v > 0; });
    Progress progress("montecarlo", B, d.rank() == 0);
    std::vector<Counters> all_counters(batch_counters.size(), Counters{});
    int done = 0;
    res.stop_reason = any_light ? "photons" : "no light";
    while (any_light && done < B) {
        const int r0 = done, r1 = std::min(B, done + round_size), cnt = r1 - r0;
        for (int b = r0 + d.rank() * cnt / P; b < r0 + (d.rank() + 1) * cnt / P; ++b) run_batch(b);
        MPI_Allreduce(batch_counters[static_cast<size_t>(r0) * nb].data(),
                      all_counters[static_cast<size_t>(r0) * nb].data(), cnt * nb * ncounters,
                      MPI_DOUBLE, MPI_SUM, d.comm());
        done = r1;
        // Relative standard error of the total diffuse power over the completed batches.
        double m = 0.0, m2 = 0.0;
        for (int b = 0; b < done; ++b) {
            double v = 0.0;
            for (int q = 0; q < nb; ++q) v += all_counters[static_cast<size_t>(b) * nb + q][diffuse_volume];
            m += v;
            m2 += v * v;
        }
        m /= done;
        const double var = std::max(0.0, m2 / done - m * m) * done / std::max(1, done - 1);
        res.rel_error = m > 0 ? std::sqrt(var / done) / m : 0.0;
        if (d.rank() == 0) {
            const double now = wall_time();
            const StopEta eta = eta_to_stop(opt, done, now - t_setup, now - t_start, res.rel_error);
            progress.update(done, eta.seconds, eta.until);
        }
        int stop = 0;
        if (d.rank() == 0 && done < B) {
            const double elapsed = wall_time() - t_start;
            const double per_round = elapsed / ((done + round_size - 1) / round_size);
            if (opt.time_budget > 0 && elapsed + per_round > opt.time_budget) stop = 1;
            if (opt.target_rel_error > 0 && done >= 2 && m > 0 && res.rel_error < opt.target_rel_error) stop = 2;
        }
        MPI_Bcast(&stop, 1, MPI_INT, 0, d.comm());
        if (stop == 1) res.stop_reason = "time_budget";
        if (stop == 2) res.stop_reason = "target_rel_error";
        if (stop) break;
    }
    progress.finish();
    const double t_traced = wall_time();
    res.batches = done;
    std::int64_t counts[3] = {my_photons, my_collisions, my_segments}, total[3] = {0, 0, 0};
    MPI_Allreduce(counts, total, 3, MPI_INT64_T, MPI_SUM, d.comm());
    res.photons = total[0];
    res.collisions = total[1];
    res.segments = total[2];

    // Counters: mean and standard error of the batch estimates.
    res.counters.assign(static_cast<size_t>(nb), Counters{});
    res.counters_stderr.assign(static_cast<size_t>(nb), Counters{});
    const double K = std::max(1, done);
    for (int q = 0; q < nb; ++q)
        for (int c = 0; c < ncounters; ++c) {
            double m = 0.0, m2 = 0.0;
            for (int b = 0; b < done; ++b) {
                const double v = all_counters[static_cast<size_t>(b) * nb + q][c];
                m += v;
                m2 += v * v;
            }
            m /= K;
            res.counters[static_cast<size_t>(q)][c] = m;
            res.counters_stderr[static_cast<size_t>(q)][c] =
                done > 1 ? std::sqrt(std::max(0.0, m2 / K - m * m) / (K - 1)) : 0.0;
        }

    // Reduce the per-cell sums to the owners of each box: pack by destination rank, only the
    // cells with density (the others are never tallied; every rank knows the replicated rho).
    auto has_density = [&](int i, int j, int k) { return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] > 0; };
    std::vector<int> recv_counts(static_cast<size_t>(P), 0);
    for (int r = 0; r < P; ++r)
        for_each_cell(d.box_of(r), [&](int i, int j, int k) {
            if (has_density(i, j, k)) recv_counts[static_cast<size_t>(r)] += nb * nq;
        });
    std::vector<double> send;
    send.reserve(static_cast<size_t>(std::accumulate(recv_counts.begin(), recv_counts.end(), std::int64_t{0})));
    for (int r = 0; r < P; ++r)
        for_each_cell(d.box_of(r), [&](int i, int j, int k) {
            if (!has_density(i, j, k)) return;
            const size_t c = static_cast<size_t>(box_index(i, j, k)) * nb;
            for (int q = 0; q < nb; ++q) {
                send.push_back(sum[c + q]);
                send.push_back(sumsq[c + q]);
                if (settings.tally_reduced) {
                    send.push_back(rsum[c + q]);
                    send.push_back(rsumsq[c + q]);
                }
            }
        });
    std::vector<double> recv(static_cast<size_t>(recv_counts[static_cast<size_t>(d.rank())]));
    MPI_Reduce_scatter(send.data(), recv.data(), recv_counts.data(), MPI_DOUBLE, MPI_SUM, d.comm());

    auto mean_and_stderr = [&](double s, double s2, double& mean, double& se) {
        mean = s / K;
        se = done > 1 ? std::sqrt(std::max(0.0, s2 / K - mean * mean) / (K - 1)) : 0.0;
    };
    for (int q = 0; q < nb; ++q) {
        res.fluence.emplace_back(d.local(), 1, 1, 0.0);
        res.fluence_stderr.emplace_back(d.local(), 1, 1, 0.0);
        if (settings.tally_reduced) {
            res.reduced.emplace_back(d.local(), 1, 1, 0.0);
            res.reduced_stderr.emplace_back(d.local(), 1, 1, 0.0);
        }
    }
    size_t pos = 0;
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (!has_density(i, j, k)) return;
        for (int q = 0; q < nb; ++q) {
            mean_and_stderr(recv[pos], recv[pos + 1], res.fluence[static_cast<size_t>(q)](i, j, k),
                            res.fluence_stderr[static_cast<size_t>(q)](i, j, k));
            pos += 2;
            if (settings.tally_reduced) {
                mean_and_stderr(recv[pos], recv[pos + 1], res.reduced[static_cast<size_t>(q)](i, j, k),
                                res.reduced_stderr[static_cast<size_t>(q)](i, j, k));
                pos += 2;
            }
        }
    });
    for (auto* v : {&res.fluence, &res.fluence_stderr, &res.reduced, &res.reduced_stderr})
        for (Field<double>& f : *v) exchange_halo(f, d);
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
