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
// The rays of one layer are translates of each other: the ray from cell (i, j, k) is the ray
// from (0, 0, k) moved by (i, j) whole cells (a light's rays are parallel, and the pieces of
// downstream rays enter a slab at points that differ by whole cells too), so they cross the
// same cells, shifted by (i, j), for the same lengths. The pass walks one ray per layer
// (ray_cells: the incremental DDA of grid_walk.h, without its empty-space jumps) and sums
// len x rho over its cells for every translate at once:
// for each row of the layer and each cell of that ray, a run of the row's sums takes len times
// a run of a density row (integrate_layer), contiguous in x, without a walk's dependent steps.
// Runs are clipped to the x range of each density row that holds density, so empty space costs
// a test per row and ray cell. 7-11x faster than a grid walk per ray (README, "Layer
// integrals"), which the pass used until the forty-second session.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/error.h"
#include "src/core/field.h"
#include "src/core/grid_walk.h"
#include "src/core/vec3.h"
#include "src/physics/lights.h"

namespace nimbus {

// A box of cells (a rank's slab, or the whole domain) prepared for the layer integrals: the
// density row by row (x fastest over box) with each row's x range of density. 8 bytes per cell.
struct RayGrid {
    std::array<bool, 3> periodic;  // the domain's x/y; never z (rays stop at z faces)
    Box box;                       // the cells covered; the domain's whole x and y ranges
    Int3 domain{0, 0, 0};          // the domain's cells
    std::vector<double> rho;       // box.cells() values, x fastest
    // Per row (j, k) of box, at (k - box.lo[2]) * box.size(1) + (j - box.lo[1]): the x range
    // [lo, hi) of its cells with density (global x; lo = hi when the row is empty).
    std::vector<int> row_lo, row_hi;
    // The grid walk's voxels (grid_walk.h: the density in Voxel::tally, the empty-space
    // distances), for ray_integral only: empty unless add_voxels. 16 bytes per cell.
    VoxelGrid voxels;
};

// box: the cells to cover (their global density from rho_of(i, j, k)), spanning the domain's x
// and y; n: the domain's cells.
template <class RhoOf>
RayGrid make_ray_grid(const Box& box, const Int3& n, const std::array<bool, 3>& domain_periodic, RhoOf&& rho_of);

// Builds g's voxels from its density (for ray_integral).
void add_voxels(RayGrid& g);

// ∫ rho ds (in cell units: multiply by h) along the ray from pos (global cell coordinates) in
// unit direction b, through the cells of g, until it leaves g's z range or, on a non-periodic
// axis, the domain's x/y range (periodic x/y wrap; g then spans the domain along them). A point
// on a cell face belongs to the cell the ray moves into. One ray's walk (grid_walk.h, with its
// empty-space jumps): the reference the layer integrals are tested against. Needs add_voxels.
double ray_integral(RayGrid& g, const Vec3& b, const std::array<double, 3>& pos);

// A cell a ray crosses (global coordinates, not wrapped around periodic axes) and the length of
// the ray in it (cell units).
struct RaySegment {
    Int3 cell;
    double len;
};

// The cells, in order, that the ray from pos in unit direction b crosses while it is inside g's z
// range and, on each non-periodic x/y axis, while the ray moved by some translate (i, j) of
// `cells` (i in [cells.lo[0], cells.hi[0]), j likewise) is still, or not yet, inside the domain:
// the cells of the ray from pos + (i, j) are these plus (i, j), wrapped on periodic axes, and
// outside the domain on a non-periodic one (density 0: the ray has left it for good). A point
// on a cell face belongs to the cell the ray moves into (as in ray_integral). The incremental
// DDA of grid_walk.h without its empty-space jumps (ties to the lower axis). A start any
// distance outside the domain is handled in double (out of int range, a start beyond the
// translates' reach is no ray). Pure; out is cleared first.
void ray_cells(const RayGrid& g, const Box& cells, const Vec3& b, const std::array<double, 3>& pos,
               std::vector<RaySegment>& out);

// Layer k of `cells` (a box inside the domain's x/y ranges): out[(j - lo_j) * nx + (i - lo_i)]
// = ∫ rho ds (cell units) along the piece through g of the ray from each cell (i, j, k), which
// starts where piece_start puts it (downstream, z_entry). Equal to ray_integral from that point
// up to round-off: the same line integral, summed in the order the ray crosses the cells, with
// the lengths of one walk (ray_integral skips empty cells, jumps through empty space and breaks
// ties between faces toward the higher axis, which moves lengths by round-off). segments:
// scratch for ray_cells (left with its periodic offsets wrapped). out holds cells' nx x ny values.
void integrate_layer(const RayGrid& g, const Box& cells, const Vec3& b, int k, bool downstream, double z_entry,
                     std::vector<RaySegment>& segments, double* out);

// Where a slab's piece of the ray from the centre of cell (i, j, k) starts: the centre itself,
// or for a cell downstream of the slab (`downstream`) the point where the ray crosses the
// slab's entry face z = z_entry (b.z != 0).
std::array<double, 3> piece_start(const Vec3& b, int i, int j, int k, bool downstream, double z_entry);

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
    const Int3 m = box.shape();
    if (box.lo[0] != 0 || box.hi[0] != n[0] || box.lo[1] != 0 || box.hi[1] != n[1])
        throw Error("make_ray_grid: the box must span the domain's x and y");
    RayGrid g;
    g.periodic = {domain_periodic[0], domain_periodic[1], false};
    g.box = box;
    g.domain = n;
    g.rho.resize(static_cast<size_t>(box.cells()));
    g.row_lo.assign(static_cast<size_t>(m[1]) * m[2], 0);
    g.row_hi.assign(static_cast<size_t>(m[1]) * m[2], 0);
    size_t c = 0;
    for_each_cell(box, [&](int i, int j, int k) {
        const double r = rho_of(i, j, k);
        g.rho[c++] = r;
        if (!(r > 0)) return;
        const size_t row = static_cast<size_t>(k - box.lo[2]) * m[1] + (j - box.lo[1]);
        if (g.row_lo[row] == g.row_hi[row]) g.row_lo[row] = i;
        g.row_hi[row] = i + 1;
    });
    return g;
}

}  // namespace nimbus
