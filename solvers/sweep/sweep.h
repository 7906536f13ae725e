// The sweep engine shared by every transport sweep (sun transmittance, DOM). Passes of whole
// groups down the slab chain (LPM z maps, the exact light pass) are in chain.h.
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

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <utility>
#include <vector>

#include "solvers/sweep/order.h"
#include "src/core/decomposition.h"
#include "src/core/error.h"
#include "src/core/field.h"
#include "src/core/mpi_counts.h"

namespace nimbus::sweep {

struct SweepOptions {
    int tile_rows = 8;       // rows (along y) per pipelined tile across the z-slab face
    int octant_overlap = 1;  // octants a caller sweeps at once with run_octants (1: one by one)
};

struct SweepStats {
    double wait_seconds = 0;  // time blocked on upstream planes (pipeline fill + imbalance)
    int tiles = 0;
};

namespace detail {

// The set-up run() and run_octants() share: the cells this rank sweeps (its box within the
// sweep's region) cut into tiles along y, and the planes it exchanges with its neighbours. The
// octant enters only through its signs.
struct Tiling {
    Box own;               // d.local() ∩ region; empty: this rank takes no part
    int ny, rows, ntiles;  // rows of own along y, rows per tile, tiles (0 when own is empty)

    // Tiles along y only when y is not split over ranks (then a y-face is whole per tile).
    Tiling(const Decomposition& d, const SweepOptions& opt, const Box& region)
        : own(d.local().intersect(region)),
          ny(own.empty() ? 0 : own.size(1)),
          rows(d.dims()[1] == 1 ? std::clamp(opt.tile_rows, 1, std::max(1, ny)) : std::max(1, ny)),
          ntiles((ny + rows - 1) / rows) {}

    // Tile t of octant o: rows [t rows, (t + 1) rows) of own (the last tile may be shorter),
    // counted from o's upwind side along y.
    Box tile(const Octant& o, int t) const {
        Box b = own;
        const int a = t * rows, e = std::min(ny, a + rows);
        if (o.s[1] > 0) { b.lo[1] = own.lo[1] + a; b.hi[1] = own.lo[1] + e; }
        else { b.lo[1] = own.hi[1] - e; b.hi[1] = own.hi[1] - a; }
        return b;
    }
    // The ghost plane just outside own on the upwind side of `axis` (the upstream rank fills it),
    // over r's extent on the other axes.
    Box upwind_plane(const Octant& o, int axis, const Box& r) const {
        const int at = o.s[axis] > 0 ? own.lo[axis] - 1 : own.hi[axis];
        return r.with_range(axis, at, at + 1);
    }
    // own's last plane on the downwind side of `axis` (sent downstream), over r's extent.
    Box downwind_plane(const Octant& o, int axis, const Box& r) const {
        const int at = o.s[axis] > 0 ? own.hi[axis] - 1 : own.lo[axis];
        return r.with_range(axis, at, at + 1);
    }
};

// The rank one step along o's direction on each axis (side +1: downstream) or against it (side
// -1: upstream). MPI_PROC_NULL at the domain boundary, along periodic axes, which are not
// swept across (the caller handles periodic sweeps by iteration), and where the region ends on
// this rank's side (its cells beyond are not swept). Not collective. On a tensor process grid
// both ranks of a pair agree: the region reaches past this rank's box toward a neighbour exactly
// when that neighbour's part of the region is not empty.
inline Int3 neighbours(const Decomposition& d, const Tiling& t, const Box& region, const Octant& o, int side) {
    Int3 r{MPI_PROC_NULL, MPI_PROC_NULL, MPI_PROC_NULL};
    if (t.own.empty()) return r;
    const Box& local = d.local();
    for (int a = 0; a < 3; ++a) {
        const int toward = side * o.s[a];  // +1: toward higher indices
        const bool beyond = toward > 0 ? region.hi[a] > local.hi[a] : region.lo[a] < local.lo[a];
        if (!d.periodic(a) && beyond) r[a] = d.neighbor(a, toward);
    }
    return r;
}

}  // namespace detail

// Collective over d.comm() (every rank calls it with the same octant and region). kernel(i, j,
// k) computes the owned cell (i, j, k) of psi, for the cells of `region` only (a box of global
// cells, d.global() for all): the cells just upwind of the region hold whatever the caller put
// there, like the ghost planes at the domain boundary, and ranks whose box misses the region
// take no part. Returns pipeline statistics of this rank.
template <class Kernel>
SweepStats run(const Decomposition& d, Field<double>& psi, const Octant& o, const SweepOptions& opt,
               Kernel&& kernel, const Box& region) {
    SweepStats stats;
    constexpr int kTag = 811;
    const detail::Tiling tiling(d, opt, region);
    const Box& own = tiling.own;
    const int ntiles = tiling.ntiles;
    if (own.empty()) return stats;
    const Int3 up = detail::neighbours(d, tiling, region, o, -1), down = detail::neighbours(d, tiling, region, o, +1);

    std::vector<double> buf;
    std::vector<std::vector<double>> out(static_cast<size_t>(ntiles) + 2);
    std::vector<MPI_Request> sends;
    auto recv_plane = [&](int axis, const Box& r) {
        if (up[axis] == MPI_PROC_NULL) return;
        const Box p = tiling.upwind_plane(o, axis, r);
        buf.resize(static_cast<size_t>(p.cells() * psi.ncomp()));
        const double t0 = MPI_Wtime();
        recv_doubles(buf, up[axis], kTag + axis, d.comm());
        stats.wait_seconds += MPI_Wtime() - t0;
        copy_cells<CopyMode::unpack>(psi, p, buf);
    };
    auto send_plane = [&](int axis, const Box& r, std::vector<double>& store) {
        if (down[axis] == MPI_PROC_NULL) return;
        copy_cells<CopyMode::pack>(psi, tiling.downwind_plane(o, axis, r), store);
        sends.emplace_back();
        isend_doubles(store, down[axis], kTag + axis, d.comm(), &sends.back());
    };

    // Whole x and y faces come first (only non-empty with 2-D/3-D process grids).
    recv_plane(0, own);
    recv_plane(1, own);
    const AxisRange rx = upwind_range(own, 0, o);
    const AxisRange rz = upwind_range(own, 2, o);
    for (int t = 0; t < ntiles; ++t) {
        const Box tile = tiling.tile(o, t);
        recv_plane(2, tile);
        const AxisRange ty = upwind_range(tile, 1, o);
        for (int k = rz.first; k != rz.end; k += rz.step)
            for (int j = ty.first; j != ty.end; j += ty.step)
                for (int i = rx.first; i != rx.end; i += rx.step) kernel(i, j, k);
        send_plane(2, tile, out[static_cast<size_t>(t)]);
        ++stats.tiles;
    }
    send_plane(0, own, out[static_cast<size_t>(ntiles)]);
    send_plane(1, own, out[static_cast<size_t>(ntiles) + 1]);
    MPI_Waitall(static_cast<int>(sends.size()), sends.data(), MPI_STATUSES_IGNORE);
    return stats;
}

// The whole domain.
template <class Kernel>
SweepStats run(const Decomposition& d, Field<double>& psi, const Octant& o, const SweepOptions& opt,
               Kernel&& kernel) {
    return run(d, psi, o, opt, std::forward<Kernel>(kernel), d.global());
}

// Several octants swept at once with data-driven scheduling (octant overlap: "octants
// overlapped so the pipe stays full", DESIGN §3). Octant q has its own field psi[q] (>= 1 ghost
// layer, any ncomp) and its own message tags, so a +z and a -z octant run concurrently from the
// opposite ends of the slab chain, and the pipeline fill of one octant is covered by another's
// work. Same tiles (detail::Tiling) and the same per-octant cell order as run(), so every psi[q]
// equals what run() gives for that octant alone, bit for bit.
//
// Scheduling: all upstream planes are pre-posted (MPI_Irecv); a rank repeatedly computes the
// next tile of any octant whose upstream planes have arrived (MPI_Test), preferring octants it
// feeds a downstream rank with (they keep the pipe full), then the lowest q; when none is ready
// it blocks in MPI_Waitany (counted as wait time). Octants are independent: whatever order the
// tiles run in, each octant's cells see their final upwind values (storage contract above).
//
// Collective over d.comm(): every rank passes the same octant list, at most kMaxOctants (more
// throws Error on every rank before any message: their tags would run into LPM's 950).
// kernel(q, i, j, k) computes owned cell (i, j, k) of psi[q]. Ghost planes at the domain
// boundary are the caller's, as in run(), and so are the cells just upwind of `region` (as in
// run()). Memory: the upstream and downstream planes of every octant in flight (one slab face
// each way, x ncomp).
constexpr int kMaxOctants = 8;

template <class Kernel>
SweepStats run_octants(const Decomposition& d, const std::vector<Field<double>*>& psi, const std::vector<Octant>& octants,
                       const SweepOptions& opt, Kernel&& kernel, const Box& region) {
    SweepStats stats;
    const int nq = static_cast<int>(octants.size());
    if (nq > kMaxOctants)
        throw Error(fmt::format("sweep::run_octants: {} octants at once, but only {} have message tags", nq,
                                kMaxOctants));
    constexpr int kTagBase = 900;  // octant q, axis a: kTagBase + 3 q + a, up to 923 (run() uses 811-813)
    const detail::Tiling tiling(d, opt, region);
    const Box& own = tiling.own;
    const int ntiles = tiling.ntiles;
    if (own.empty()) return stats;

    struct State {
        Field<double>* psi = nullptr;
        Octant o;
        Int3 up{}, down{};
        int next = 0;                                  // next tile
        MPI_Request face_req[2] = {MPI_REQUEST_NULL, MPI_REQUEST_NULL};  // whole x / y faces
        std::vector<double> face_buf[2];
        std::vector<MPI_Request> z_req;                // per tile
        std::vector<std::vector<double>> z_buf;        // per tile
        bool faces_unpacked = false;
    };
    std::vector<State> st(static_cast<size_t>(nq));
    std::vector<MPI_Request> sends;
    std::vector<std::vector<double>> out;  // send buffers, alive until the final Waitall
    out.reserve(static_cast<size_t>(nq * (ntiles + 2)));

    // Pre-post every receive, in tile order (same source and tag: MPI keeps them in order).
    for (int q = 0; q < nq; ++q) {
        State& s = st[static_cast<size_t>(q)];
        s.psi = psi[static_cast<size_t>(q)];
        s.o = octants[static_cast<size_t>(q)];
        s.up = detail::neighbours(d, tiling, region, s.o, -1);
        s.down = detail::neighbours(d, tiling, region, s.o, +1);
        const int nc = s.psi->ncomp();
        for (int a = 0; a < 2; ++a) {
            if (s.up[a] == MPI_PROC_NULL) continue;
            auto& b = s.face_buf[a];
            b.resize(static_cast<size_t>(tiling.upwind_plane(s.o, a, own).cells() * nc));
            irecv_doubles(b, s.up[a], kTagBase + 3 * q + a, d.comm(), &s.face_req[a]);
        }
        s.z_req.assign(static_cast<size_t>(ntiles), MPI_REQUEST_NULL);
        s.z_buf.resize(static_cast<size_t>(ntiles));
        if (s.up[2] == MPI_PROC_NULL) continue;
        for (int t = 0; t < ntiles; ++t) {
            auto& b = s.z_buf[static_cast<size_t>(t)];
            b.resize(static_cast<size_t>(tiling.upwind_plane(s.o, 2, tiling.tile(s.o, t)).cells() * nc));
            irecv_doubles(b, s.up[2], kTagBase + 3 * q + 2, d.comm(), &s.z_req[static_cast<size_t>(t)]);
        }
    }
    // The request octant q's next tile still waits for (nullptr: ready).
    auto pending = [&](State& s) -> MPI_Request* {
        for (int a = 0; a < 2; ++a) {
            int done = 0;
            MPI_Test(&s.face_req[a], &done, MPI_STATUS_IGNORE);
            if (!done) return &s.face_req[a];
        }
        MPI_Request* r = &s.z_req[static_cast<size_t>(s.next)];
        int done = 0;
        MPI_Test(r, &done, MPI_STATUS_IGNORE);
        return done ? nullptr : r;
    };
    auto send = [&](State& s, int q, int axis, const Box& r) {
        if (s.down[axis] == MPI_PROC_NULL) return;
        out.emplace_back();
        copy_cells<CopyMode::pack>(*s.psi, tiling.downwind_plane(s.o, axis, r), out.back());
        sends.emplace_back();
        isend_doubles(out.back(), s.down[axis], kTagBase + 3 * q + axis, d.comm(), &sends.back());
    };
    auto run_tile = [&](State& s, int q) {
        if (!s.faces_unpacked) {
            for (int a = 0; a < 2; ++a)
                if (s.up[a] != MPI_PROC_NULL)
                    copy_cells<CopyMode::unpack>(*s.psi, tiling.upwind_plane(s.o, a, own), s.face_buf[a]);
            s.faces_unpacked = true;
        }
        const Box tile = tiling.tile(s.o, s.next);
        if (s.up[2] != MPI_PROC_NULL)
            copy_cells<CopyMode::unpack>(*s.psi, tiling.upwind_plane(s.o, 2, tile), s.z_buf[static_cast<size_t>(s.next)]);
        const AxisRange rx = upwind_range(own, 0, s.o), ty = upwind_range(tile, 1, s.o), rz = upwind_range(own, 2, s.o);
        for (int k = rz.first; k != rz.end; k += rz.step)
            for (int j = ty.first; j != ty.end; j += ty.step)
                for (int i = rx.first; i != rx.end; i += rx.step) kernel(q, i, j, k);
        send(s, q, 2, tile);
        ++stats.tiles;
        if (++s.next == ntiles) {
            send(s, q, 0, own);
            send(s, q, 1, own);
        }
    };
    std::vector<MPI_Request*> waiting;
    std::vector<MPI_Request> wait_req;
    for (int left = nq * ntiles; left > 0;) {
        int pick = -1;
        waiting.clear();
        for (int pass = 0; pass < 2 && pick < 0; ++pass)
            for (int q = 0; q < nq && pick < 0; ++q) {
                State& s = st[static_cast<size_t>(q)];
                if (s.next == ntiles || (pass == 0) != (s.down[2] != MPI_PROC_NULL)) continue;
                MPI_Request* r = pending(s);
                if (r == nullptr) pick = q;
                else waiting.push_back(r);
            }
        if (pick >= 0) {
            run_tile(st[static_cast<size_t>(pick)], pick);
            --left;
            continue;
        }
        wait_req.clear();
        for (MPI_Request* r : waiting) wait_req.push_back(*r);
        int idx = MPI_UNDEFINED;
        const double t0 = MPI_Wtime();
        MPI_Waitany(static_cast<int>(wait_req.size()), wait_req.data(), &idx, MPI_STATUS_IGNORE);
        stats.wait_seconds += MPI_Wtime() - t0;
        if (idx != MPI_UNDEFINED) *waiting[static_cast<size_t>(idx)] = MPI_REQUEST_NULL;
    }
    MPI_Waitall(static_cast<int>(sends.size()), sends.data(), MPI_STATUSES_IGNORE);
    return stats;
}

// The whole domain.
template <class Kernel>
SweepStats run_octants(const Decomposition& d, const std::vector<Field<double>*>& psi, const std::vector<Octant>& octants,
                       const SweepOptions& opt, Kernel&& kernel) {
    return run_octants(d, psi, octants, opt, std::forward<Kernel>(kernel), d.global());
}

}  // namespace nimbus::sweep
