// The bounding box of the cells that satisfy a predicate, over all ranks: where the DOM sweeps
// (solvers/dom/transport_sweep.h, TransportSweeper::region) and the diffusion solve
// (solvers/diffusion/solve_region.h) confine their work.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <array>

#include "src/core/box.h"
#include "src/core/decomposition.h"
#include "src/core/field.h"

namespace nimbus {

// The bounding box of the cells (i, j, k) of `within` where in(i, j, k); empty (hi = lo) when
// there are none. Not collective.
template <class In>
Box local_bounding_box(const Box& within, In&& in) {
    Box b{within.hi, within.lo};  // inverted: the first cell found sets both ends
    for_each_cell(within, [&](int i, int j, int k) {
        if (!in(i, j, k)) return;
        const int c[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
            b.lo[a] = std::min(b.lo[a], c[a]);
            b.hi[a] = std::max(b.hi[a], c[a] + 1);
        }
    });
    return b.hi[0] > b.lo[0] ? b : Box{within.lo, within.lo};
}

// Collective. The bounding box (global cells) of the cells (i, j, k) of d.local() where
// in(i, j, k), over all ranks, whole along periodic axes; empty when there are none.
template <class In>
Box bounding_box(const Decomposition& d, In&& in) {
    const Box& g = d.global();
    const Box mine = local_bounding_box(d.local(), in);
    std::array<int, 6> ext{};  // -lo and hi, so that one MAX reduction gives both
    for (int a = 0; a < 3; ++a) {
        ext[static_cast<size_t>(a)] = mine.empty() ? -g.hi[a] : -mine.lo[a];
        ext[static_cast<size_t>(3 + a)] = mine.empty() ? g.lo[a] : mine.hi[a];
    }
    MPI_Allreduce(MPI_IN_PLACE, ext.data(), 6, MPI_INT, MPI_MAX, d.comm());
    Box b;
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = -ext[static_cast<size_t>(a)];
        b.hi[a] = ext[static_cast<size_t>(3 + a)];
    }
    if (b.empty()) return Box{g.lo, g.lo};
    for (int a = 0; a < 3; ++a)
        if (d.periodic(a)) b = b.with_range(a, g.lo[a], g.hi[a]);
    return b;
}

}  // namespace nimbus
