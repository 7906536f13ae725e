// The sweep engine shared by every transport sweep (sun transmittance now; DOM and LPM next).
// Pipelines a sweep over the process grid in KBA style (Koch, Baker, Alcouffe 1992): a rank
// computes its box in upwind order once its upstream neighbours' boundary planes have arrived.
// Along z (the slab chain), the box is cut into tiles of rows across the slab face so the
// downstream rank starts as soon as the first tile's plane arrives, instead of waiting for the
// whole slab.
//
// Storage contract: the swept quantity lives in a cell-centred Field<double> `psi` with >= 1
// ghost layer and ncomp values per cell (e.g. one per angle of an angle group). When kernel(i,
// j, k) runs, the upwind neighbours (i - s_x, j, k), (i, j - s_y, k), (i, j, k - s_z) hold their
// final values: owned cells computed earlier, ghost cells received from the upstream rank, or
// (at the domain boundary) whatever the caller put in the ghosts before the sweep.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <vector>

#include "solvers/sweep/order.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus::sweep {

struct SweepOptions {
    int tile_rows = 8;  // rows (along y) per pipelined tile across the z-slab face
};

struct SweepStats {
    double wait_seconds = 0;  // time blocked on upstream planes (pipeline fill + imbalance)
    int tiles = 0;
};

namespace detail {

// Copies the plane `at` of axis over the cell range r (other axes) between psi and buf.
template <bool kPack>
inline void copy_plane(Field<double>& psi, int axis, int at, const Box& r, std::vector<double>& buf) {
    Box p = r;
    p.lo[axis] = at;
    p.hi[axis] = at + 1;
    const int nc = psi.ncomp();
    buf.resize(static_cast<size_t>(p.cells() * nc));
    size_t n = 0;
    for_each_cell(p, [&](int i, int j, int k) {
        double* v = &psi(i, j, k);
        for (int c = 0; c < nc; ++c, ++n) {
            if constexpr (kPack) buf[n] = v[c]; else v[c] = buf[n];
        }
    });
}

}  // namespace detail

// Collective over d.comm() (every rank calls it with the same octant). kernel(i, j, k) computes
// the owned cell (i, j, k) of psi. Returns pipeline statistics of this rank.
template <class Kernel>
SweepStats run(const Decomposition& d, Field<double>& psi, const Octant& o, const SweepOptions& opt,
               Kernel&& kernel) {
    SweepStats stats;
    const Box& own = d.local();
    constexpr int kTag = 811;
    // Upstream/downstream neighbour per axis (MPI_PROC_NULL at the domain boundary; periodic
    // axes are not swept across: the caller handles periodic sweeps by iteration).
    Int3 up{}, down{};
    for (int a = 0; a < 3; ++a) {
        up[a] = d.periodic(a) ? MPI_PROC_NULL : d.neighbor(a, -o.s[a]);
        down[a] = d.periodic(a) ? MPI_PROC_NULL : d.neighbor(a, o.s[a]);
    }
    // Tiles along y only when y is not split over ranks (then a y-face is whole per tile).
    const int ny = own.size(1);
    const int rows = (d.dims()[1] == 1) ? std::clamp(opt.tile_rows, 1, std::max(1, ny)) : std::max(1, ny);
    const int ntiles = (ny + rows - 1) / rows;
    // Ghost planes that the upstream ranks fill: the plane just outside own box on the upwind side.
    auto upwind_ghost = [&](int a) { return o.s[a] > 0 ? own.lo[a] - 1 : own.hi[a]; };
    auto downwind_edge = [&](int a) { return o.s[a] > 0 ? own.hi[a] - 1 : own.lo[a]; };

    std::vector<double> buf;
    std::vector<std::vector<double>> out(static_cast<size_t>(ntiles) + 2);
    std::vector<MPI_Request> sends;
    auto recv_plane = [&](int axis, const Box& r) {
        if (up[axis] == MPI_PROC_NULL) return;
        Box p = r;
        p.lo[axis] = upwind_ghost(axis);
        p.hi[axis] = p.lo[axis] + 1;
        buf.resize(static_cast<size_t>(p.cells() * psi.ncomp()));
        const double t0 = MPI_Wtime();
        MPI_Recv(buf.data(), static_cast<int>(buf.size()), MPI_DOUBLE, up[axis], kTag + axis, d.comm(),
                 MPI_STATUS_IGNORE);
        stats.wait_seconds += MPI_Wtime() - t0;
        detail::copy_plane<false>(psi, axis, p.lo[axis], r, buf);
    };
    auto send_plane = [&](int axis, const Box& r, std::vector<double>& store) {
        if (down[axis] == MPI_PROC_NULL) return;
        detail::copy_plane<true>(psi, axis, downwind_edge(axis), r, store);
        sends.emplace_back();
        MPI_Isend(store.data(), static_cast<int>(store.size()), MPI_DOUBLE, down[axis], kTag + axis,
                  d.comm(), &sends.back());
    };

    // Whole x and y faces come first (only non-empty with 2-D/3-D process grids).
    recv_plane(0, own);
    recv_plane(1, own);
    const AxisRange ry = upwind_range(own, 1, o);
    const AxisRange rx = upwind_range(own, 0, o);
    const AxisRange rz = upwind_range(own, 2, o);
    for (int t = 0; t < ntiles; ++t) {
        // Tile t covers rows [j0, j1) in upwind order along y.
        Box tile = own;
        const int a = t * rows, b = std::min(ny, a + rows);
        if (o.s[1] > 0) { tile.lo[1] = own.lo[1] + a; tile.hi[1] = own.lo[1] + b; }
        else { tile.lo[1] = own.hi[1] - b; tile.hi[1] = own.hi[1] - a; }
        recv_plane(2, tile);
        const AxisRange ty = upwind_range(tile, 1, o);
        for (int k = rz.first; k != rz.end; k += rz.step)
            for (int j = ty.first; j != ty.end; j += ty.step)
                for (int i = rx.first; i != rx.end; i += rx.step) kernel(i, j, k);
        send_plane(2, tile, out[static_cast<size_t>(t)]);
        ++stats.tiles;
    }
    (void)ry;
    send_plane(0, own, out[static_cast<size_t>(ntiles)]);
    send_plane(1, own, out[static_cast<size_t>(ntiles) + 1]);
    MPI_Waitall(static_cast<int>(sends.size()), sends.data(), MPI_STATUSES_IGNORE);
    return stats;
}

}  // namespace nimbus::sweep
