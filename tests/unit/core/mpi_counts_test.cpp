// Collectives beyond MPI's int counts (src/core/mpi_counts.h), exercised with a small `limit`
// in place of 2^31 - 1: the blocked and the pieced paths give what the plain calls give.
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <vector>

#include "src/core/error.h"
#include "src/core/mpi_counts.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

// Rank r contributes 6 (r + 1) values (whole "layers" of 6): Allgatherv in blocks of the gcd 6
// when the limit is below the largest count, and in elements otherwise, gathers the same.
TEST(MpiCounts, AllgathervInBlocksEqualsElements) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    std::vector<std::int64_t> counts, displs;
    std::int64_t off = 0;
    for (int r = 0; r < size; ++r) counts.push_back(6 * (r + 1)), displs.push_back(off), off += counts.back();
    std::vector<double> mine(static_cast<size_t>(counts[static_cast<size_t>(rank)]));
    std::iota(mine.begin(), mine.end(), 1000.0 * rank);
    std::vector<double> want(static_cast<size_t>(off)), got(want.size());
    for (int r = 0; r < size; ++r)
        for (std::int64_t q = 0; q < counts[static_cast<size_t>(r)]; ++q)
            want[static_cast<size_t>(displs[static_cast<size_t>(r)] + q)] = 1000.0 * r + static_cast<double>(q);
    for (std::int64_t limit : {std::int64_t{INT_MAX}, std::int64_t{5}}) {
        const BlockCounts bc(MPI_COMM_WORLD, counts, displs, MPI_DOUBLE, {static_cast<std::int64_t>(mine.size())}, limit);
        EXPECT_EQ(bc.block(), limit == 5 ? 6 : 1);
        std::fill(got.begin(), got.end(), -1.0);
        MPI_Allgatherv(mine.data(), bc.blocks(static_cast<std::int64_t>(mine.size())), bc.type(), got.data(),
                       bc.counts(), bc.displs(), bc.type(), MPI_COMM_WORLD);
        EXPECT_EQ(got, want) << "limit " << limit;
    }
    // Counts whose blocks still exceed the limit (9 elements in blocks of gcd(6, 9) = 3 against a
    // limit of 2): an error on every rank.
    EXPECT_THROW(BlockCounts(MPI_COMM_WORLD, {6, 9}, {0, 6}, MPI_DOUBLE, {}, 2), Error);
    EXPECT_NO_THROW(BlockCounts(MPI_COMM_WORLD, {6, 9}, {0, 6}, MPI_DOUBLE, {}, 3));
}

// Every rank sends r + 10 q for destination q's 7 values: the pieced path (limit 3) sums the
// same as MPI_Reduce_scatter.
TEST(MpiCounts, ReduceScatterInPiecesEqualsTheCollective) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const std::vector<std::int64_t> counts(static_cast<size_t>(size), 7);
    std::vector<double> send;
    for (int q = 0; q < size; ++q)
        for (int e = 0; e < 7; ++e) send.push_back(rank + 10.0 * q + 0.5 * e);
    const std::vector<double> plain = reduce_scatter_sum(MPI_COMM_WORLD, send, counts);
    const std::vector<double> pieces = reduce_scatter_sum(MPI_COMM_WORLD, send, counts, 3);
    ASSERT_EQ(plain.size(), 7u);
    EXPECT_EQ(pieces, plain);
    const double ranks_sum = size * (size - 1) / 2.0;
    for (int e = 0; e < 7; ++e) EXPECT_EQ(plain[static_cast<size_t>(e)], ranks_sum + size * (10.0 * rank + 0.5 * e));
}

}  // namespace
}  // namespace nimbus
