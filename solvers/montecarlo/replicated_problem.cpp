#include "solvers/montecarlo/replicated_problem.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "src/core/empty_space.h"
#include "src/core/error.h"
#include "src/core/gather.h"
#include "src/core/log.h"

namespace nimbus::mc {

ReplicatedProblem replicate_problem(const Decomposition& d, const Medium& medium,
                                    const std::vector<DirectionalLight>& lights,
                                    const std::vector<VolumeSource>& sources, const MonteCarloOptions& opt,
                                    const ForwardSettings& settings) {
    ReplicatedProblem p;
    p.n = d.global().hi;
    p.h = medium.grid.h;
    p.nb = medium.nbands();
    p.periodic = {d.periodic(0), d.periodic(1), d.periodic(2)};
    p.lights = lights;
    p.groups = group_by_optics(medium.bands);  // traced once per group
    for (const OpticsGroup& g : p.groups)
        if (g.bands.size() > 64) throw Error("Monte Carlo supports at most 64 bands with equal optics");
    const Int3& n = p.n;

    // Memory of the replicated arrays, per rank (replicated_bytes, forward.h).
    double source_cells = 0.0;
    for (const VolumeSource& src : sources) source_cells += static_cast<double>(src.cells.cells());
    const double bytes = replicated_bytes(static_cast<double>(d.global().cells()), static_cast<int>(p.groups.size()),
                                          p.nb, settings.tally_reduced, source_cells, settings.tally_flux);
    p.replicated_gb = bytes / 1e9;
    check_replicated_memory(n, bytes, opt);

    p.rho = allgather_global(medium.rho, d);
    const std::vector<double>& rho = p.rho;

    // Bounding box of the non-empty cells (the whole extent along periodic axes): where the
    // lights' photons enter.
    Int3& box_lo = p.entry_lo;
    Int3& box_hi = p.entry_hi;
    box_lo = n;
    for_each_cell(d.global(), [&](int i, int j, int k) {
        if (p.has_density(i, j, k)) {
            const Int3 c{i, j, k};
            for (int a = 0; a < 3; ++a) box_lo[a] = std::min(box_lo[a], c[a]), box_hi[a] = std::max(box_hi[a], c[a] + 1);
        }
    });
    for (int a = 0; a < 3; ++a)
        if (p.periodic[a] || box_hi[a] <= box_lo[a]) box_lo[a] = 0, box_hi[a] = p.periodic[a] ? n[a] : 0;

    // The walk's grid covers only that box (outside it all is empty), or the whole domain when
    // the empty cells are tallied too, padded by one ghost layer (grid_walk.h); the per-cell
    // arrays use the walk's cell indices.
    p.empty_cells = opt.empty_cells;
    p.box_lo = opt.empty_cells ? Int3{0, 0, 0} : box_lo;
    p.box_hi = opt.empty_cells ? n : box_hi;
    const Int3& box_n = p.box_n;
    for (int a = 0; a < 3; ++a) p.box_n[a] = std::max(p.box_hi[a] - p.box_lo[a], 1);
    p.padded_cells = static_cast<std::int64_t>(box_n[0] + 2) * (box_n[1] + 2) * (box_n[2] + 2);

    // Light terms: entry faces, projected area (m²) of the domain and of the box's live pixels
    // (photon.h: rays through the rest meet only empty cells), photon counts.
    std::vector<double> power;
    const std::vector<Int3> surface = surface_cells(
        {box_hi[0] - box_lo[0], box_hi[1] - box_lo[1], box_hi[2] - box_lo[2]}, p.periodic,
        [&](const Int3& c) { return p.has_density(c[0] + box_lo[0], c[1] + box_lo[1], c[2] + box_lo[2]); });
    const double h = p.h;
    for (const DirectionalLight& L : lights) {
        p.domain_area.push_back(EntrySampler({0, 0, 0}, n, p.periodic, L.w).projected_area * h * h);
        p.entry.emplace_back(box_lo, box_hi, p.periodic, L.w);
        p.entry.back().restrict_to(surface, p.periodic, L.w);
        p.area.push_back(p.entry.back().projected_area * h * h);
        double pw = 0.0;
        for (int b = 0; b < p.nb; ++b) pw += L.E0[static_cast<size_t>(b)] * p.area.back();
        power.push_back(pw);
    }
    // Volume sources: the emitting cells of each, then its power, after the lights' (one
    // budget, photons_per_light).
    for (const VolumeSource& src : sources) {
        p.emitters.emplace_back(src.power, src.cells, [&](int i, int j, int k) {
            return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i];
        }, h);
        double pw = 0.0;
        for (int b = 0; b < p.nb; ++b) pw += p.emitters.back().total_power(b);
        power.push_back(pw);
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
    p.n_light = photons_per_light(power, opt.photons, opt.batches);
    const std::int64_t n_total = std::accumulate(p.n_light.begin(), p.n_light.end(), std::int64_t{0});
    if (n_total > opt.photons)
        log::warn("montecarlo: {} photon{} asked for, {} traced: every lit term takes at least one photon per "
                  "batch ({} terms, {} batches)",
                  opt.photons, opt.photons == 1 ? "" : "s", n_total, std::count_if(power.begin(), power.end(), [](double v) { return v > 0; }),
                  opt.batches);

    // One padded voxel grid per optics group: kappa in 1/cell over the walked box.
    p.voxels.resize(p.groups.size());
    const Int3 &walk_lo = p.box_lo, &walk_hi = p.box_hi;
    std::vector<float> kappa(static_cast<size_t>(box_n[0]) * box_n[1] * box_n[2], 0.0f);
    for (size_t gi = 0; gi < p.groups.size(); ++gi) {
        for (int k = walk_lo[2]; k < walk_hi[2]; ++k)
            for (int j = walk_lo[1]; j < walk_hi[1]; ++j)
                for (int i = walk_lo[0]; i < walk_hi[0]; ++i)
                    kappa[(static_cast<size_t>(k - walk_lo[2]) * box_n[1] + (j - walk_lo[1])) * box_n[0] + (i - walk_lo[0])] =
                        static_cast<float>(rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] * p.groups[gi].optics.sigma_t * h);
        p.voxels[gi] = make_voxels(box_n, kappa);
        p.voxels[gi].origin = walk_lo;
        p.voxels[gi].domain = n;
    }
    return p;
}

}  // namespace nimbus::mc
