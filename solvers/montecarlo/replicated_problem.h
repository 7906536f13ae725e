// What every rank of the forward Monte Carlo model traces (forward.h): the density grid
// replicated on every rank, the walked box (the bounding box of the non-empty cells, the whole
// extent along periodic axes; the whole domain with MonteCarloOptions::empty_cells), one padded
// voxel grid per optics group (grid_walk.h), and the light terms: where each light's photons
// enter (photon.h, EntrySampler on the live pixels of the bounding box of the non-empty
// cells), the volume sources' emitters (emitter.h), and each term's share of the photons.
//
// Per-cell arrays of the forward model are indexed like the voxel grids: box_index(i, j, k) of a
// domain cell inside the box, padded_cells values in all.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "solvers/montecarlo/emitter.h"
#include "solvers/montecarlo/forward.h"
#include "solvers/montecarlo/photon.h"
#include "src/core/box.h"
#include "src/core/grid_walk.h"
#include "src/scene/optics_groups.h"

namespace nimbus::mc {

struct ReplicatedProblem {
    Int3 n{0, 0, 0};  // domain cells
    double h = 0.0;   // cell edge, m
    int nb = 0;       // bands
    std::array<bool, 3> periodic{false, false, false};
    std::vector<double> rho;  // the global density, x fastest
    double replicated_gb = 0.0;  // per-rank memory of the replicated arrays (replicated_bytes)

    Int3 entry_lo{0, 0, 0}, entry_hi{0, 0, 0};  // bounding box of the non-empty cells, domain cells
                                                // [lo, hi), the whole extent along periodic axes (empty: no density)
    bool empty_cells = false;                // the empty cells' fluence is tallied (MonteCarloOptions)
    Int3 box_lo{0, 0, 0}, box_hi{0, 0, 0};  // the walked box: entry_lo/hi, or the domain with empty_cells
    Int3 box_n{1, 1, 1};                     // its cells per axis, at least 1 (the voxel grids' n)
    std::int64_t padded_cells = 0;           // of the box with its ghost layer

    std::vector<OpticsGroup> groups;  // bands traced together (equal optics)
    std::vector<VoxelGrid> voxels;    // per group: kappa of the box, padded

    std::vector<DirectionalLight> lights;
    std::vector<EntrySampler> entry;          // per light
    std::vector<double> area, domain_area;    // per light: projected area of the live pixels, of the domain (m²)
    std::vector<VolumeEmitter> emitters;      // per volume source
    std::vector<std::int64_t> n_light;        // photons per term: lights, then sources

    size_t light_terms() const { return lights.size(); }
    size_t terms() const { return lights.size() + emitters.size(); }
    bool has_density(int i, int j, int k) const {
        return rho[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] > 0;
    }
    // Whether the forward model estimates the fluence of cell (i, j, k).
    bool tallied(int i, int j, int k) const { return empty_cells || has_density(i, j, k); }
    // Index of domain cell (i, j, k), inside the box, into the padded per-cell arrays.
    std::int64_t box_index(int i, int j, int k) const {
        return GridView{box_n, periodic, nullptr}.index({i - box_lo[0], j - box_lo[1], k - box_lo[2]});
    }
};

// Replicates medium.rho on every rank and builds the rest. Collective over d.comm(). Throws
// Error (on every rank alike) when the replicated arrays would exceed
// opt.max_replicated_memory_gb, when a term's power is not finite, or with more than 64 bands
// of equal optics; warns when the one-photon-per-batch minimum raises the photon count.
ReplicatedProblem replicate_problem(const Decomposition& d, const Medium& medium,
                                    const std::vector<DirectionalLight>& lights,
                                    const std::vector<VolumeSource>& sources, const MonteCarloOptions& opt,
                                    const ForwardSettings& settings);

}  // namespace nimbus::mc
