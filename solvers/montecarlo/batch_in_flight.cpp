#include "solvers/montecarlo/batch_in_flight.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "solvers/montecarlo/trace_lanes.h"
#include "solvers/montecarlo/trace_light.h"

namespace nimbus::mc {

KeptBatches::KeptBatches(const ReplicatedProblem& p, const ForwardSettings& settings)
    : sum(static_cast<size_t>(p.padded_cells * p.nb), 0.0), sumsq(sum.size(), 0.0) {
    if (settings.tally_reduced) rsum.assign(sum.size(), 0.0), rsumsq.assign(sum.size(), 0.0);
    if (settings.tally_flux) fsum.assign(3 * sum.size(), 0.0);
}

BatchInFlight::BatchInFlight(ReplicatedProblem& p, const MonteCarloOptions& opt, const ForwardSettings& settings,
                             bool lanes, KeptBatches& kept)
    : p_(p), opt_(opt), settings_(settings), kept_(kept),
      tally_(static_cast<size_t>(p.padded_cells) * p.nb, 0.0),
      counters_(static_cast<size_t>(p.nb), Counters{}),
      lanes_(lanes && !settings.forced_first_collision && !settings.tally_reduced) {
    if (settings.tally_reduced)
        rtally_.assign(tally_.size(), 0.0), reduced_acc_.assign(static_cast<size_t>(p.padded_cells), 0.0);
    if (settings.tally_flux) flux_acc_.assign(4 * static_cast<size_t>(p.padded_cells), 0.0);
    // Batches are dropped only at a time budget or a target error (forward.h).
    if (settings.tally_flux && (opt.time_budget > 0 || opt.target_rel_error > 0)) flux_.assign(3 * tally_.size(), 0.0);
    const auto cells = static_cast<size_t>(std::min<std::int64_t>(p.padded_cells, 1 << 20));
    light_touched_.reserve(cells);
    touched_.reserve(cells);
}

template <class Visit>
void BatchInFlight::for_each_listed(const std::vector<std::int64_t>& list, Visit&& visit) const {
    // A scan costs ~1 ns a cell, a list entry a cache miss.
    const std::int64_t f = settings_.fold_scan_fraction;
    if (f == 0 || static_cast<std::int64_t>(list.size()) * f < p_.padded_cells) {
        for (const std::int64_t idx : list) visit(idx);
    } else {  // every cell once; the unlisted ones fold zeros, which changes no sum
        for (std::int64_t idx = 0; idx < p_.padded_cells; ++idx) visit(idx);
    }
}

void BatchInFlight::trace(int batch, int layout, std::int64_t k0, std::int64_t k1, std::int64_t steps) {
    auto offset = [steps](std::int64_t count, std::int64_t k) {  // count k / steps, exactly
        return count / steps * k + count % steps * k / steps;
    };
    const double h = p_.h;
    const size_t nl = p_.light_terms();
    for (size_t gi = 0; gi < p_.groups.size(); ++gi) {
        const OpticsGroup& G = p_.groups[gi];
        const int nbg = static_cast<int>(G.bands.size());
        const int* band = G.bands.data();
        const GridView grid = p_.voxels[gi].view(p_.periodic);
        const PhotonOptics po{G.optics.albedo, G.optics.g, opt_.roulette_weight};
        // The open fold class: consecutive terms whose per-band scales are proportional (one
        // colour, e.g. the sky's directions) share the voxel accumulators, each term's track
        // scaled by its ratio alpha to the class's first term, and are folded once.
        FoldClass fc;
        for (size_t l = 0; l < p_.terms(); ++l) {
            const std::int64_t N = p_.n_light[l];
            if (N == 0) continue;
            const VolumeEmitter* emitter = l < nl ? nullptr : &p_.emitters[l - nl];
            // b N / layout, exactly, without b N (which overflows once N > 2^33 and the batches
            // are split towards 2^30).
            auto part = [&](std::int64_t b) { return N / layout * b + N % layout * b / layout; };
            const std::int64_t lo = part(batch), hi = part(batch + 1);
            if (hi <= lo) continue;
            const std::int64_t from = lo + offset(hi - lo, k0), to = lo + offset(hi - lo, k1);
            // Photon power per band (W) in this batch's estimate, and the fluence scale
            // P len(m) / V = P len(cells) / h².
            double P[64]{}, scale[64]{};
            int strongest = 0;
            for (int q = 0; q < nbg; ++q) {
                P[q] = (emitter ? emitter->total_power(band[q])
                                : p_.lights[l].E0[static_cast<size_t>(band[q])] * p_.area[l]) /
                       static_cast<double>(hi - lo);
                scale[q] = P[q] / (h * h);
                if (scale[q] > scale[strongest]) strongest = q;
            }
            if (!(scale[strongest] > 0)) {  // no power in this group's bands (nothing to tally)
                if (gi == 0) photons_ += to - from;
                continue;
            }
            if (k0 == 0)  // once per batch: the term's power, and the rays that miss the box
                for (int q = 0; q < nbg; ++q) {
                    Counters& c = counters_[static_cast<size_t>(band[q])];
                    if (emitter) {
                        c[emitted] += emitter->total_power(band[q]);
                    } else {
                        const double E0 = p_.lights[l].E0[static_cast<size_t>(band[q])];
                        c[incident] += E0 * p_.domain_area[l];
                        c[escaped_direct] += E0 * (p_.domain_area[l] - p_.area[l]);
                    }
                }
            if (to <= from) continue;
            const double alpha = fc.open && !settings_.fold_by_colour ? 0.0 : fc.join(nbg, P, scale, strongest);
            if (alpha == 0.0) {  // another colour: fold the class so far, start a new one
                fold_class(fc, grid, band, nbg);
                fc.join(nbg, P, scale, strongest);
            }
            // Trace (w len alpha accumulated per voxel); fold_class folds the accumulators.
            PathTally pt;
            LightTerm term{emitter ? nullptr : &p_.entry[l], emitter ? Vec3{0, 0, -1} : p_.lights[l].w, emitter,
                           static_cast<std::uint32_t>(l)};
            term.tally_scale = alpha == 0.0 ? 1.0 : alpha;
            term.empty_cells = p_.empty_cells;
            double* const flux = settings_.tally_flux ? flux_acc_.data() : nullptr;
            if (lanes_)
                trace_photons_lanes(grid, po, term, opt_.seed, from, to, light_touched_, pt, flux);
            else
                trace_photons(grid, po, term, opt_.seed, from, to, settings_.forced_first_collision,
                              settings_.tally_reduced ? reduced_acc_.data() : nullptr, light_touched_, pt, flux);
            if (gi == 0) photons_ += to - from;  // a photon traced once per optics group
            collisions_ += pt.collisions;
            segments_ += pt.segments;
            for (int q = 0; q < nbg; ++q) {
                Counters& c = counters_[static_cast<size_t>(band[q])];
                c[absorbed] += P[q] * pt.absorbed;
                c[escaped_direct] += P[q] * pt.escaped_direct;
                for (int f = 0; f < 6; ++f) c[escaped_xlo + f] += P[q] * pt.escaped_diffuse[f];
                c[roulette_net] += P[q] * pt.roulette_net;
            }
        }
        fold_class(fc, grid, band, nbg);
    }
}

double BatchInFlight::FoldClass::join(int nbg, const double* P_term, const double* scale_term, int strongest_term) {
    if (!open) {
        std::copy(P_term, P_term + nbg, P);
        std::copy(scale_term, scale_term + nbg, scale);
        strongest = strongest_term;
        open = true;
        return 1.0;
    }
    // Proportional to the class's scales to 1e-12 in every band (the sky's directions are one
    // colour times a weight; the rounding of those products is far below this).
    const double alpha = scale_term[strongest] / scale[strongest];
    for (int q = 0; q < nbg; ++q)
        if (!(std::abs(scale_term[q] - alpha * scale[q]) <= 1e-12 * scale_term[q])) return 0.0;
    return alpha;
}

void BatchInFlight::fold_class(FoldClass& fc, const GridView& grid, const int* band, int nbg) {
    if (!fc.open) return;
    fc.open = false;
    // Fold the class's accumulators into the per-band batch tally (x the class's P/h² per band)
    // and zero them. A cell is listed in touched_ when its tally of the class's strongest band
    // is still 0 (every tallied segment adds a positive amount there; a repeated entry folds 0,
    // harmlessly).
    const int nb = p_.nb;
    auto fold = [&](std::vector<double>& to_tally, std::int64_t idx, double track) {
        double* c = to_tally.data() + idx * nb;
        if (c[band[fc.strongest]] == 0.0) touched_.push_back(idx);
        for (int q = 0; q < nbg; ++q) c[band[q]] += track * fc.scale[q];
    };
    double diffuse_track = 0.0;  // sum of w len alpha (cells) after the first scattering, in the medium
    for_each_listed(light_touched_, [&](std::int64_t idx) {
        const double v = std::exchange(grid.voxel[idx].tally, 0.0);
        if (grid.voxel[idx].kappa > 0.0f) diffuse_track += v;  // empty cells (empty_cells) aside
        if (v != 0.0) fold(tally_, idx, v);
        if (!flux_acc_.empty() && v != 0.0) {  // a cell with a collision has fluence: listed here
            double* acc = flux_acc_.data() + 4 * idx;
            if (acc[0] != 0.0 || acc[1] != 0.0 || acc[2] != 0.0) {
                double* f = (flux_.empty() ? kept_.fsum.data() : flux_.data()) + 3 * idx * nb;
                for (int q = 0; q < nbg; ++q)
                    for (int a = 0; a < 3; ++a) f[3 * band[q] + a] += acc[a] * fc.scale[q];
                acc[0] = acc[1] = acc[2] = 0.0;
            }
        }
        if (settings_.tally_reduced) {
            const double r = std::exchange(reduced_acc_[static_cast<size_t>(idx)], 0.0);
            if (r != 0.0) fold(rtally_, idx, r);
        }
    });
    light_touched_.clear();
    for (int q = 0; q < nbg; ++q) counters_[static_cast<size_t>(band[q])][diffuse_volume] += fc.P[q] * diffuse_track * p_.h;
}

void BatchInFlight::end(bool keep) {
    KeptBatches& kept = kept_;
    const int nb = p_.nb;
    auto fold = [&](std::vector<double>& from, std::vector<double>& s1, std::vector<double>& s2, std::int64_t c) {
        double* v = from.data() + c * nb;
        for (int q = 0; q < nb; ++q) {
            if (keep) {
                s1[static_cast<size_t>(c * nb + q)] += v[q];
                s2[static_cast<size_t>(c * nb + q)] += v[q] * v[q];
            }
            v[q] = 0.0;
        }
    };
    for_each_listed(touched_, [&](std::int64_t c) {
        fold(tally_, kept.sum, kept.sumsq, c);
        if (!flux_.empty()) {
            double* v = flux_.data() + 3 * c * nb;
            double* s = kept.fsum.data() + 3 * c * nb;
            for (int q = 0; q < 3 * nb; ++q) {
                if (keep) s[q] += v[q];
                v[q] = 0.0;
            }
        }
        if (settings_.tally_reduced) fold(rtally_, kept.rsum, kept.rsumsq, c);
    });
    touched_.clear();
    if (keep) {
        kept.photons += photons_;
        kept.collisions += collisions_;
        kept.segments += segments_;
    }
    photons_ = collisions_ = segments_ = 0;
    std::fill(counters_.begin(), counters_.end(), Counters{});
}

}  // namespace nimbus::mc
