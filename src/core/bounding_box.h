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

// Collective. The bounding box (global cells) of the cells (i, j, k) of d.local() where
// in(i, j, k), over all ranks, whole along periodic axes; empty when there are none.
template <class In>
Box bounding_box(const Decomposition& d, In&& in) {
    const Box& g = d.global();
    std::array<int, 6> ext{};  // -lo and hi, so that one MAX reduction gives both
    for (int a = 0; a < 3; ++a) {
        ext[static_cast<size_t>(a)] = -g.hi[a];
        ext[static_cast<size_t>(3 + a)] = g.lo[a];
    }
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (!in(i, j, k)) return;
        const int c[3] = {i, j, k};
        for (size_t a = 0; a < 3; ++a) {
            ext[a] = std::max(ext[a], -c[a]);
            ext[3 + a] = std::max(ext[3 + a], c[a] + 1);
        }
    });
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
