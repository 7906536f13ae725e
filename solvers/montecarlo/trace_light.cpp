#include "solvers/montecarlo/trace_light.h"

namespace nimbus::mc {

namespace {

template <bool kEmptyCells>
[[gnu::always_inline]] inline void trace_range(const GridView& grid, const PhotonOptics& optics,
                                               const LightTerm& term, std::uint64_t seed, std::int64_t lo,
                                               std::int64_t hi, bool forced_first_collision, double* reduced,
                                               std::vector<std::int64_t>& lit, PathTally& out, double* flux) {
    Voxel* const voxel = grid.voxel;
    const double ts = term.tally_scale;  // 1 exactly for a term that starts its fold class
    auto diffuse = [voxel, ts, &lit, &out](std::int64_t idx, double wl) {
        ++out.segments;
        double& a = voxel[idx].tally;
        if (a == 0.0) lit.push_back(idx);
        a += wl * ts;
    };
    auto uncollided = [reduced, ts, &lit](std::int64_t idx, double track) {
        if (reduced[idx] == 0.0) lit.push_back(idx);
        reduced[idx] += track * ts;
    };
    for (std::int64_t p = lo; p < hi; ++p) {
        PathRng rng(seed, term.stream, static_cast<std::uint64_t>(p));
        PathState s;
        // The flux's collision estimator (photon.h): (w s / kappa) d, d = s.d the flight's direction.
        auto collision = [voxel, ts, flux, &s](std::int64_t idx, double w) {
            if (!flux) return;
            const double wk = w * ts / static_cast<double>(voxel[idx].kappa);
            double* f = flux + 4 * idx;
            f[0] += wk * s.d.x;
            f[1] += wk * s.d.y;
            f[2] += wk * s.d.z;
        };
        if (term.emitter) {
            term.emitter->sample(rng, grid, s);
            trace_emitted_photon<kEmptyCells>(grid, optics, rng, s, out, diffuse, collision);
            continue;
        }
        s.d = term.w;
        term.entry->sample(rng, grid, s);
        if (reduced)
            trace_photon<true, kEmptyCells>(grid, optics, rng, s, out, diffuse, collision, uncollided,
                                            forced_first_collision);
        else
            trace_photon<false, kEmptyCells>(grid, optics, rng, s, out, diffuse, collision,
                                             [](std::int64_t, double) {}, forced_first_collision);
    }
}

}  // namespace

// The kernels of photon.h and grid_walk.h are always_inline (trace_range too), so each clone
// compiles its own copy of the whole path loop for its target, once per kEmptyCells.
__attribute__((target_clones("arch=x86-64-v3", "default")))
void trace_photons(const GridView& grid, const PhotonOptics& optics, const LightTerm& term, std::uint64_t seed,
                   std::int64_t lo, std::int64_t hi, bool forced_first_collision, double* reduced,
                   std::vector<std::int64_t>& lit, PathTally& out, double* flux) {
    if (term.empty_cells)
        trace_range<true>(grid, optics, term, seed, lo, hi, forced_first_collision, reduced, lit, out, flux);
    else
        trace_range<false>(grid, optics, term, seed, lo, hi, forced_first_collision, reduced, lit, out, flux);
}

}  // namespace nimbus::mc
