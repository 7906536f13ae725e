// Exact light pass pipelined down the slab chain (long characteristics without replication).
// Every cell centre's ray back toward the light is integrated exactly through the piecewise-
// constant cells. The ray from a cell crosses the slabs of the ranks upstream of it; each rank
// integrates, for every ray that crosses its slab, the piece inside its own slab (only its own
// density is needed), and the partial sums travel down the chain one rank's worth of rays at a
// time: rank r receives from its upstream neighbour the partial sums of the rays of rank q (q =
// r, then each rank further downstream), adds its own piece, keeps the result if q = r and
// passes it on otherwise. The tracing has no dependency on other ranks, so it all overlaps; only
// the additions wait. Work: a rank traces every ray that crosses its slab, so ranks nearer the
// light trace more (the price of not replicating the density).
//
// The rays are walked by the grid walk of the Monte Carlo paths (src/core/grid_walk.h): exact
// cell traversal that crosses empty regions in one step per empty cube (empty_space.h), which
// made the default cloud's 9 light terms ~2.5x cheaper than a cell-by-cell march. The cells'
// rays are traced in columns along the light (for_each_cell_along), so that each ray finds the
// cells the previous one crossed still in cache: 1.7-1.9x faster than x-fastest order on 128³
// and 256³ (jobs/bench_foundation.sh), where the walk used to wait on its voxel loads.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/empty_space.h"
#include "src/core/field.h"
#include "src/core/grid_walk.h"
#include "src/core/vec3.h"
#include "src/physics/lights.h"

namespace nimbus {

// A box of cells (a rank's slab, or the whole domain) prepared for ray integrals: the walk's
// voxels mark the non-empty cells and their empty-space distances, and each voxel's double
// (Voxel::tally, the Monte Carlo's accumulator) holds the cell's density, so the sums stay in
// double precision and a step reads one 16-byte voxel (16 bytes per cell in all).
struct RayGrid {
    VoxelGrid voxels;
    std::array<bool, 3> periodic;  // of the walk: the domain's x/y; never z (rays stop at z faces)
};

// box: the cells to cover (their global density from rho_of(i, j, k)); n: the domain's cells.
template <class RhoOf>
RayGrid make_ray_grid(const Box& box, const Int3& n, const std::array<bool, 3>& domain_periodic, RhoOf&& rho_of);

// ∫ rho ds (in cell units: multiply by h) along the ray from pos (global cell coordinates) in
// unit direction b, through the cells of g, until it leaves g's z range or, on a non-periodic
// axis, the domain's x/y range (periodic x/y wrap; g then spans the domain along them). A point
// on a cell face belongs to the cell the ray moves into. Pure.
double ray_integral(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos);
// The same for two rays of direction b at once, walked in lockstep (walk_through_pair): the
// two integrals ray_integral gives, bit for bit, in 70-75% of the time.
void ray_integral_pair(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos_a,
                       const std::array<double, 3>& pos_b, double& integral_a, double& integral_b);

// ray_integral for every cell of box, in for_each_cell_along's order and two rays at a time:
// start(i, j, k) gives where the cell's ray starts, store(i, j, k, p, integral) takes the result
// (p: the cell's x-fastest index in box).
template <class Start, class Store>
void integrate_rays_along(RayGrid& g, const Box& box, const Vec3& b, Start&& start, Store&& store);

// The walk's state for that ray (ray_integral's start): false if pos is outside g's cells.
bool ray_start(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos, PathState& s);

// Where a slab's piece of the ray from the centre of cell (i, j, k) starts: the centre itself,
// or for a cell downstream of the slab (`downstream`) the point where the ray crosses the
// slab's entry face z = z_entry (b.z != 0).
std::array<double, 3> piece_start(const Vec3& b, int i, int j, int k, bool downstream, double z_entry);

// Calls fn(i, j, k, p) once for every cell of box, p being the cell's index in x-fastest order
// (for_each_cell's), in an order that keeps consecutive rays toward the light on the same cells:
// columns of tile x tile cells sheared along b (layer k shifted by floor(k b_xy / b_z) cells, so
// a column follows one ray line), each column from its lowest layer to its highest. A cell's ray
// then crosses what the ray of the cell below it crossed one step earlier, and the walk finds
// its cells in cache; in x-fastest order the next ray over the same cells came a whole layer
// of rays later. Horizontal or nearly horizontal b (a shear wider than the box allows) keeps
// x-fastest order. The results do not depend on the order: every ray is integrated on its own.
template <class Fn>
void for_each_cell_along(const Box& box, const Vec3& b, Fn&& fn, int tile = 8);

// Collective over d.comm(); slabs along z. tau_rho (owned box, ghosts untouched) of one light;
// slab = make_slab_grid(d, rho) (built once for all lights). busy_seconds (if given) gets this
// rank's time in the pass not spent waiting on the chain: its tracing, whose spread over the
// ranks is the chain's imbalance.
RayGrid make_slab_grid(const Decomposition& d, const Field<double>& rho);
void exact_tau_chain(const Decomposition& d, RayGrid& slab, double h, const DirectionalLight& light,
                     Field<double>& tau, double* busy_seconds = nullptr);

// ---------------------------------------------------------------------------------------------

template <class RhoOf>
RayGrid make_ray_grid(const Box& box, const Int3& n, const std::array<bool, 3>& domain_periodic, RhoOf&& rho_of) {
    const std::array<int, 3> m{box.hi[0] - box.lo[0], box.hi[1] - box.lo[1], box.hi[2] - box.lo[2]};
    // kappa only marks the non-empty cells (the integral reads rho): a density too small for a
    // float stays non-empty.
    std::vector<float> mark(static_cast<size_t>(box.cells()), 0.0f);
    size_t c = 0;
    for_each_cell(box, [&](int i, int j, int k) {
        const double r = rho_of(i, j, k);
        mark[c++] = r > 0 ? std::max(static_cast<float>(r), std::numeric_limits<float>::min()) : 0.0f;
    });
    RayGrid g{make_voxels(m, mark), {domain_periodic[0], domain_periodic[1], false}};
    g.voxels.origin = {box.lo[0], box.lo[1], box.lo[2]};
    g.voxels.domain = {n[0], n[1], n[2]};
    const GridView v = g.voxels.view(g.periodic);
    for_each_cell(box, [&](int i, int j, int k) {
        v.voxel[v.index({i - box.lo[0], j - box.lo[1], k - box.lo[2]})].tally = rho_of(i, j, k);
    });
    return g;
}

template <class Start, class Store>
void integrate_rays_along(RayGrid& g, const Box& box, const Vec3& b, Start&& start, Store&& store) {
    bool held = false;  // a ray waiting for its partner
    std::array<double, 3> held_pos{};
    std::array<int, 3> held_cell{};
    std::int64_t held_p = 0;
    for_each_cell_along(box, b, [&](int i, int j, int k, std::int64_t p) {
        const std::array<double, 3> pos = start(i, j, k);
        if (!held) {
            held = true, held_pos = pos, held_cell = {i, j, k}, held_p = p;
            return;
        }
        double first, second;
        ray_integral_pair(g, b, held_pos, pos, first, second);
        store(held_cell[0], held_cell[1], held_cell[2], held_p, first);
        store(i, j, k, p, second);
        held = false;
    });
    if (held) store(held_cell[0], held_cell[1], held_cell[2], held_p, ray_integral(g, b, held_pos));
}

template <class Fn>
void for_each_cell_along(const Box& box, const Vec3& b, Fn&& fn, int tile) {
    const Int3 m = box.shape();
    if (box.empty()) return;
    tile = std::max(tile, 1);
    auto plain = [&] {
        std::int64_t p = 0;
        for_each_cell(box, [&](int i, int j, int k) { fn(i, j, k, p++); });
    };
    // Cells per layer that a ray line moves along x and y; the column loop below runs
    // tiles x layers iterations, so a shear that makes them many times the cells is not worth it.
    const double sx = b.x / b.z, sy = b.y / b.z;  // b.z = 0: inf or nan, refused below
    const double reach_x = std::abs(sx) * m[2], reach_y = std::abs(sy) * m[2];
    if (!(reach_x <= 4.0 * m[0] + 64 && reach_y <= 4.0 * m[1] + 64)) return plain();
    std::vector<int> ox(static_cast<size_t>(m[2])), oy(static_cast<size_t>(m[2]));
    for (int k = 0; k < m[2]; ++k) {
        ox[static_cast<size_t>(k)] = floor_to_int(sx * k);
        oy[static_cast<size_t>(k)] = floor_to_int(sy * k);
    }
    const auto [ox_lo, ox_hi] = std::minmax_element(ox.begin(), ox.end());
    const auto [oy_lo, oy_hi] = std::minmax_element(oy.begin(), oy.end());
    // Layer k's cell i is column i - ox[k], in [-max ox, m0 - min ox): the tiles cover that range.
    for (int tj = -*oy_hi; tj < m[1] - *oy_lo; tj += tile)
        for (int ti = -*ox_hi; ti < m[0] - *ox_lo; ti += tile)
            for (int k = 0; k < m[2]; ++k) {
                const int i0 = std::max(0, ti + ox[static_cast<size_t>(k)]);
                const int i1 = std::min(m[0], ti + tile + ox[static_cast<size_t>(k)]);
                const int j0 = std::max(0, tj + oy[static_cast<size_t>(k)]);
                const int j1 = std::min(m[1], tj + tile + oy[static_cast<size_t>(k)]);
                for (int j = j0; j < j1; ++j)
                    for (int i = i0; i < i1; ++i)
                        fn(box.lo[0] + i, box.lo[1] + j, box.lo[2] + k,
                           (static_cast<std::int64_t>(k) * m[1] + j) * m[0] + i);
            }
}

}  // namespace nimbus
