#include "src/core/halo.h"

#include <fmt/format.h>

#include <vector>

#include "src/core/error.h"
#include "src/core/mpi_counts.h"

namespace nimbus {

namespace {

// The exchange of both overloads: with each adjacent rank whose part of `within` is not empty,
// when this rank's is not either (the decision is the same on both sides).
void exchange_parts(Field<double>& f, const Decomposition& d, const Box& within) {
    const int g = f.ghost();
    const Box& own = f.owned();
    const bool mine = !own.empty();
    const auto partner = [&](int rank) {
        return rank != MPI_PROC_NULL && mine && !d.box_of(rank).intersect(within).empty() ? rank : MPI_PROC_NULL;
    };
    std::vector<double> send, recv;
    for (int axis = 0; axis < 3; ++axis) {
        const int lo_nb = partner(d.neighbor(axis, -1)), hi_nb = partner(d.neighbor(axis, +1));
        const int depth = std::min(g, own.size(axis));  // own.size < g only alone on a periodic axis
        for (int dir : {+1, -1}) {
            // dir = +1: send my high layers up, receive my low ghosts from below.
            const int to = dir > 0 ? hi_nb : lo_nb, from = dir > 0 ? lo_nb : hi_nb;
            const int s0 = dir > 0 ? own.hi[axis] - depth : own.lo[axis];
            const int r0 = dir > 0 ? own.lo[axis] - depth : own.hi[axis];
            // Slabs over the allocated extent of the other axes, so edges and corners propagate.
            const Box ss = f.allocated().with_range(axis, s0, s0 + depth);
            const Box rs = f.allocated().with_range(axis, r0, r0 + depth);
            if (to != MPI_PROC_NULL) copy_cells<CopyMode::pack>(f, ss, send);
            else send.clear();
            recv.resize(from != MPI_PROC_NULL ? static_cast<size_t>(rs.cells() * f.ncomp()) : 0);
            sendrecv_doubles(send, to, recv, from, 700 + axis, d.comm());
            if (from != MPI_PROC_NULL) copy_cells<CopyMode::unpack>(f, rs, recv);
        }
    }
}

}  // namespace

void exchange_halo(Field<double>& f, const Decomposition& d) {
    const int g = f.ghost();
    if (g == 0) return;
    // Every ghost comes from the adjacent rank: each box must be at least g cells thick. The
    // boxes are known everywhere, so every rank throws alike (no rank left waiting).
    for (int axis = 0; axis < 3; ++axis)
        if (d.dims()[axis] > 1 && d.thinnest(axis) < g)
            throw Error(fmt::format("a field with {} ghost layers needs every rank's box at least {} cells thick "
                                    "along {}, but {} ranks split its {} cells into boxes of {}; use fewer ranks",
                                    g, g, "xyz"[axis], d.dims()[axis], d.global().size(axis), d.thinnest(axis)));
    exchange_parts(f, d, d.global());
}

void exchange_halo(Field<double>& f, const Decomposition& d, const Box& within) {
    // One layer: a part is then never thinner than the ghosts it sends (a part is at least one
    // cell thick, or empty).
    bool whole = true;  // along the periodic axes, where the wrap joins the two ends
    for (int a = 0; a < 3; ++a)
        whole = whole && (!d.periodic(a) || (within.lo[a] <= d.global().lo[a] && within.hi[a] >= d.global().hi[a]));
    if (f.ghost() != 1 || f.owned() != d.local().intersect(within) || !whole)
        throw Error("exchange_halo: a field on a part of the rank's box needs one ghost layer, owned = "
                    "d.local() ∩ within, and `within` whole along the periodic axes");
    exchange_parts(f, d, within);
}

void accumulate_halo(Field<double>& f, const Decomposition& d, int axis) {
    const Box& own = f.owned();
    check_collective(d.comm(), f.ghost() == 1, "accumulate_halo: fields with one ghost layer only");
    std::vector<double> send, recv;
    for (int dir : {+1, -1}) {
        // dir = +1: my high ghost layer goes up, into the neighbour's lowest owned layer.
        const int to = d.neighbor(axis, dir), from = d.neighbor(axis, -dir);
        const int ghost = dir > 0 ? own.hi[axis] : own.lo[axis] - 1;
        const int edge = dir > 0 ? own.lo[axis] : own.hi[axis] - 1;
        const Box ss = f.allocated().with_range(axis, ghost, ghost + 1);
        const Box rs = f.allocated().with_range(axis, edge, edge + 1);
        if (to != MPI_PROC_NULL) copy_cells<CopyMode::pack>(f, ss, send);
        else send.clear();
        recv.assign(from != MPI_PROC_NULL ? static_cast<size_t>(rs.cells() * f.ncomp()) : 0, 0.0);
        sendrecv_doubles(send, to, recv, from, 720 + axis, d.comm());
        if (from != MPI_PROC_NULL) copy_cells<CopyMode::add>(f, rs, recv);
    }
    const int nc = f.ncomp();
    for_each_cell(f.allocated(), [&](int i, int j, int k) {
        if (!own.contains(i, j, k))
            for (int c = 0; c < nc; ++c) f(i, j, k, c) = 0.0;
    });
}

}  // namespace nimbus
