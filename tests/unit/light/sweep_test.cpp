// The sweep engine: upwind neighbours are final when a cell is computed, across tiles and ranks,
// for every octant; the pipelined result equals a serial sweep.
#include <gtest/gtest.h>

#include "solvers/sweep/sweep.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {


TEST(Sweep, MatchesSerialRecurrenceForEveryOctant) {
    const Int3 n{5, 7, 6};
    const Decomposition d(MPI_COMM_WORLD, n);
    for (int oct = 0; oct < 8; ++oct) {
        const sweep::Octant o{{oct & 1 ? 1 : -1, oct & 2 ? 1 : -1, oct & 4 ? 1 : -1}};
        Field<double> psi(d.local(), 1, 2, 0.0);
        sweep::SweepOptions opt;
        opt.tile_rows = 2;
        sweep::run(d, psi, o, opt, [&](int i, int j, int k) {
            for (int c = 0; c < 2; ++c)
                psi(i, j, k, c) = (c + 1) + 0.5 * (psi(i - o.s[0], j, k, c) + psi(i, j - o.s[1], k, c) +
                                                   psi(i, j, k - o.s[2], c));
        });
        // Serial reference on the whole grid.
        Field<double> ref(Box{{0, 0, 0}, n}, 1, 2, 0.0);
        const auto rx = sweep::upwind_range(ref.owned(), 0, o), ry = sweep::upwind_range(ref.owned(), 1, o),
                   rz = sweep::upwind_range(ref.owned(), 2, o);
        for (int k = rz.first; k != rz.end; k += rz.step)
            for (int j = ry.first; j != ry.end; j += ry.step)
                for (int i = rx.first; i != rx.end; i += rx.step)
                    for (int c = 0; c < 2; ++c)
                        ref(i, j, k, c) = (c + 1) + 0.5 * (ref(i - o.s[0], j, k, c) + ref(i, j - o.s[1], k, c) +
                                                           ref(i, j, k - o.s[2], c));
        for_each_cell(d.local(), [&](int i, int j, int k) {
            for (int c = 0; c < 2; ++c) ASSERT_EQ(psi(i, j, k, c), ref(i, j, k, c)) << "octant " << oct;
        });
    }
}

TEST(Sweep, WorksOnAProcessGridAlongX) {
    const Int3 n{8, 3, 4};
    const Decomposition d(MPI_COMM_WORLD, n, {test::world_size(), 1, 1});
    const sweep::Octant o{{-1, 1, 1}};
    Field<double> psi(d.local(), 1, 1, 0.0);
    sweep::run(d, psi, o, {}, [&](int i, int j, int k) { psi(i, j, k) = 1 + psi(i + 1, j, k); });
    for_each_cell(d.local(), [&](int i, int j, int k) { ASSERT_EQ(psi(i, j, k), n[0] - i); });
}

}  // namespace
}  // namespace nimbus
