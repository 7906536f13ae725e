// Volume emission of the scene's [[sources]] (SourceSpec, scene.h), as the models use it.
//
//   a source covers the cells whose centre c (scene units, from the domain's low corner)
//   satisfies lo <= c < hi on every axis: an index box, source_cells();
//   a covered cell emits power[b] W/m³ (all directions) in band b if its density is > 0,
//   i.e. the isotropic radiance source q_b = power[b] / 4π W/m³/sr (RTE of DESIGN §1);
//   overlapping sources add.
//
// Empty cells never emit: emission is a property of the medium (Monte Carlo walks and the
// diffusion solve do not even represent empty cells). A source whose covered cells are all
// empty is an error (check_volume_sources), because it would silently do nothing.
// Header-only; everything but check_volume_sources is pure (no MPI).
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "src/core/box.h"
#include "src/core/decomposition.h"
#include "src/core/error.h"
#include "src/scene/medium.h"
#include "src/scene/scene.h"

namespace nimbus {

// The global index box of the cells whose centres lie in [s.lo, s.hi) (empty box if none).
inline Box source_cells(const SourceSpec& s, const GridSpec& g) {
    Box b;
    const double cs = g.cell_size;
    auto centre = [cs](int i) { return (i + 0.5) * cs; };
    // First index whose centre is >= x, clamped to [0, n]; the estimate is corrected exactly.
    auto first_at_or_above = [&](double x, int n) {
        double est = std::ceil(x / cs - 0.5);
        int i = est < 0 ? 0 : est > n ? n : static_cast<int>(est);
        while (i > 0 && centre(i - 1) >= x) --i;
        while (i < n && centre(i) < x) ++i;
        return i;
    };
    for (int a = 0; a < 3; ++a) {
        const auto ua = static_cast<size_t>(a);
        b.lo[a] = first_at_or_above(s.lo[ua], g.n[ua]);
        b.hi[a] = std::max(b.lo[a], first_at_or_above(s.hi[ua], g.n[ua]));
    }
    return b;
}

// A source resolved on the grid: its covered index box and its power per band (W/m³, one
// value per band of the scene). Same on every rank.
struct VolumeSource {
    Box cells;
    std::vector<double> power;
};

inline std::vector<VolumeSource> volume_sources(const Scene& scene) {
    std::vector<VolumeSource> out;
    for (const SourceSpec& s : scene.sources) {
        VolumeSource v{source_cells(s, scene.grid), {}};
        for (int b = 0; b < scene.nbands(); ++b)
            v.power.push_back(s.power.size() == 1 ? s.power[0] : s.power[static_cast<size_t>(b)]);
        out.push_back(std::move(v));
    }
    return out;
}

// Emitted power density (W/m³, all directions) of cell (i, j, k) in band b: the sum over the
// sources covering it, 0 in empty cells. rho must hold (i, j, k). A ghost cell across a
// periodic face passes the domain cell it wraps to as `domain_cell` (the sources' boxes are in
// domain cells); otherwise it is (i, j, k).
// The same at given strengths: strength(s) W/m³ for source s (a right-hand side's weights over
// the volume-source terms, band_groups.h) instead of band b's powers.
template <class Strength>
double emitted_power_at(const std::vector<VolumeSource>& sources, const Field<double>& rho, Strength&& strength,
                        int i, int j, int k, const Int3& domain_cell) {
    if (!(rho(i, j, k) > 0)) return 0.0;
    double p = 0.0;
    for (size_t s = 0; s < sources.size(); ++s)
        if (sources[s].cells.contains(domain_cell[0], domain_cell[1], domain_cell[2])) p += strength(s);
    return p;
}

inline double emitted_power(const std::vector<VolumeSource>& sources, const Field<double>& rho,
                            int b, int i, int j, int k, const Int3& domain_cell) {
    return emitted_power_at(
        sources, rho, [&](size_t s) { return sources[s].power[static_cast<size_t>(b)]; }, i, j, k, domain_cell);
}

inline double emitted_power(const std::vector<VolumeSource>& sources, const Field<double>& rho,
                            int b, int i, int j, int k) {
    return emitted_power(sources, rho, b, i, j, k, {i, j, k});
}

// Collective over d.comm(). Throws Error on every rank if a source with non-zero power covers
// no cell with density (its emission would be silently lost). rho holds d.local().
inline void check_volume_sources(const std::vector<VolumeSource>& sources, const Field<double>& rho,
                                 const Decomposition& d) {
    const size_t ns = sources.size();
    if (ns == 0) return;
    std::vector<std::int64_t> live(ns, 0);
    for (size_t s = 0; s < ns; ++s)
        for_each_cell(sources[s].cells.intersect(d.local()),
                      [&](int i, int j, int k) { live[s] += rho(i, j, k) > 0 ? 1 : 0; });
    MPI_Allreduce(MPI_IN_PLACE, live.data(), static_cast<int>(ns), MPI_INT64_T, MPI_SUM, d.comm());
    for (size_t s = 0; s < ns; ++s) {
        double total = 0.0;
        for (double p : sources[s].power) total += p;
        if (total > 0 && live[s] == 0)
            throw Error(
                fmt::format("sources[{}] covers no cell with density: volume emission comes only "
                            "from the medium (cells with density > 0)",
                            s));
    }
}

}  // namespace nimbus
