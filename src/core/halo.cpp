#include "src/core/halo.h"

#include <fmt/format.h>

#include <vector>

#include "src/core/error.h"

namespace nimbus {
namespace {

enum class Slab { pack, unpack, add };

// Copies the slab of f between [a, b) along `axis` (other axes over the allocated box, so
// edges and corners propagate) to a buffer (pack), or from it (unpack), or adds it in (add).
template <Slab kMode>
void copy_slab(Field<double>& f, int axis, int a, int b, std::vector<double>& buf) {
    Box s = f.allocated();
    s.lo[axis] = a;
    s.hi[axis] = b;
    const int nc = f.ncomp();
    buf.resize(static_cast<size_t>(s.cells() * nc));
    size_t n = 0;
    for_each_cell(s, [&](int i, int j, int k) {
        for (int c = 0; c < nc; ++c, ++n) {
            if constexpr (kMode == Slab::pack) buf[n] = f(i, j, k, c);
            else if constexpr (kMode == Slab::unpack) f(i, j, k, c) = buf[n];
            else f(i, j, k, c) += buf[n];
        }
    });
}

}  // namespace

void exchange_halo(Field<double>& f, const Decomposition& d) {
    const int g = f.ghost();
    if (g == 0) return;
    const Box& own = f.owned();
    // Every ghost comes from the adjacent rank: each box must be at least g cells thick. The
    // boxes are known everywhere, so every rank throws alike (no rank left waiting).
    for (int axis = 0; axis < 3; ++axis)
        if (d.dims()[axis] > 1 && d.thinnest(axis) < g)
            throw Error(fmt::format("a field with {} ghost layers needs every rank's box at least {} cells thick "
                                    "along {}, but {} ranks split its {} cells into boxes of {}; use fewer ranks",
                                    g, g, "xyz"[axis], d.dims()[axis], d.global().size(axis), d.thinnest(axis)));
    std::vector<double> send, recv;
    for (int axis = 0; axis < 3; ++axis) {
        const int lo_nb = d.neighbor(axis, -1), hi_nb = d.neighbor(axis, +1);
        const int depth = std::min(g, own.size(axis));  // own.size < g only alone on a periodic axis
        for (int dir : {+1, -1}) {
            // dir = +1: send my high layers up, receive my low ghosts from below.
            const int to = dir > 0 ? hi_nb : lo_nb, from = dir > 0 ? lo_nb : hi_nb;
            const int s0 = dir > 0 ? own.hi[axis] - depth : own.lo[axis];
            const int r0 = dir > 0 ? own.lo[axis] - depth : own.hi[axis];
            if (to != MPI_PROC_NULL) copy_slab<Slab::pack>(f, axis, s0, s0 + depth, send);
            else send.clear();
            Box rs = f.allocated();
            rs.lo[axis] = r0;
            rs.hi[axis] = r0 + depth;
            recv.resize(from != MPI_PROC_NULL ? static_cast<size_t>(rs.cells() * f.ncomp()) : 0);
            MPI_Sendrecv(send.data(), static_cast<int>(send.size()), MPI_DOUBLE, to, 700 + axis,
                         recv.data(), static_cast<int>(recv.size()), MPI_DOUBLE, from, 700 + axis,
                         d.comm(), MPI_STATUS_IGNORE);
            if (from != MPI_PROC_NULL) copy_slab<Slab::unpack>(f, axis, r0, r0 + depth, recv);
        }
    }
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
        if (to != MPI_PROC_NULL) copy_slab<Slab::pack>(f, axis, ghost, ghost + 1, send);
        else send.clear();
        Box rs = f.allocated();
        rs.lo[axis] = edge;
        rs.hi[axis] = edge + 1;
        recv.assign(from != MPI_PROC_NULL ? static_cast<size_t>(rs.cells() * f.ncomp()) : 0, 0.0);
        MPI_Sendrecv(send.data(), static_cast<int>(send.size()), MPI_DOUBLE, to, 720 + axis, recv.data(),
                     static_cast<int>(recv.size()), MPI_DOUBLE, from, 720 + axis, d.comm(), MPI_STATUS_IGNORE);
        if (from != MPI_PROC_NULL) copy_slab<Slab::add>(f, axis, edge, edge + 1, recv);
    }
    const int nc = f.ncomp();
    for_each_cell(f.allocated(), [&](int i, int j, int k) {
        if (!own.contains(i, j, k))
            for (int c = 0; c < nc; ++c) f(i, j, k, c) = 0.0;
    });
}

}  // namespace nimbus
