// move_cells: a distributed array moved between two splits of the same grid keeps every
// cell's value, and moving back restores it; values that do not fit one rank's box are an
// Error on every rank.
#include <gtest/gtest.h>

#include "src/core/error.h"
#include "src/core/field.h"
#include "src/core/relayout.h"
#include "tests/support/expect_collective_error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

double value_of(int i, int j, int k) { return i + 100.0 * j + 10000.0 * k + 0.25; }

std::vector<double> values_on(const Box& b) {
    std::vector<double> v;
    for_each_cell(b, [&](int i, int j, int k) { v.push_back(value_of(i, j, k)); });
    return v;
}

TEST(Relayout, MovesCellsBetweenSlabSplitsAndBack) {
    const int P = test::world_size();
    const Int3 n{3, 2, 4 * P + 1};
    const Decomposition even(MPI_COMM_WORLD, n);
    // Thin slabs at the top: slab p (p < P - 1) has one layer, the bottom one the rest.
    std::vector<int> cuts{0, n[2] - (P - 1)};
    for (int p = 1; p < P; ++p) cuts.push_back(cuts.back() + 1);
    if (P == 1) cuts = {0, n[2]};
    const Decomposition top_thin = even.with_cuts(2, cuts);
    const std::vector<double> moved = move_cells(even, values_on(even.local()), top_thin);
    EXPECT_EQ(moved, values_on(top_thin.local()));
    EXPECT_EQ(move_cells(top_thin, moved, even), values_on(even.local()));
    EXPECT_THROW(move_cells(even, std::vector<double>(3), top_thin), Error);
    // Short values on the last rank only: one Error on every rank, not a hang in the exchange.
    std::vector<double> short_on_last = values_on(even.local());
    if (test::world_rank() == P - 1) short_on_last.pop_back();
    test::expect_collective_error([&] { move_cells(even, short_on_last, top_thin); },
                                  "move_cells: the values do not cover this rank's box");
}

TEST(Relayout, MovesCellsBetweenProcessGrids) {
    // Any two splits over the same communicator's ranks: slabs along z and along x.
    const int P = test::world_size();
    const Int3 n{2 * P + 1, 3, 5};
    const Decomposition z(MPI_COMM_WORLD, n);
    const Decomposition x(MPI_COMM_WORLD, n, {P, 1, 1});
    EXPECT_EQ(move_cells(z, values_on(z.local()), x), values_on(x.local()));
}

}  // namespace
}  // namespace nimbus
