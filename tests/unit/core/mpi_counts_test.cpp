// Collectives and messages beyond MPI's int counts (src/core/mpi_counts.h), exercised with a
// small `limit` in place of 2^31 - 1: the blocked, derived-type and pieced paths give what the
// plain calls give. The block choice is checked at real sizes beyond 2^31 (arithmetic only).
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <vector>

#include "src/core/error.h"
#include "src/core/mpi_counts.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

// Blocks for counts beyond 2^31 - 1: within int themselves, and leaving counts within int.
TEST(MpiCounts, BlockChoiceAtRealSizes) {
    const std::int64_t two31 = std::int64_t{1} << 31;
    EXPECT_EQ(choose_block(6, 2000, INT_MAX), 1);  // everything fits: no block
    // One rank with 3 x 2^31 elements (counts {N}, displs {0}: the gcd is N itself, not an int).
    EXPECT_EQ(choose_block(3 * two31, 3 * two31, INT_MAX), 3 * two31 / 4);
    // 1024³ cells x 9 components in two slabs: gcd 9 x 2^29, blocks of 3 x 2^29, counts of 3.
    EXPECT_EQ(choose_block(9 * (two31 / 4), 9 * (two31 / 4), INT_MAX), 3 * (two31 / 4));
    // A gcd just past the limit: its largest divisor within it.
    EXPECT_EQ(choose_block(2 * std::int64_t{INT_MAX}, 2 * std::int64_t{INT_MAX}, INT_MAX), INT_MAX);
    // 2^31 + 11 is prime: only blocks of 1, which leave the count above the limit.
    EXPECT_EQ(choose_block(two31 + 11, two31 + 11, INT_MAX), 0);
    // Small divisors only (a gcd of 4 x 7, a limit of 5): 4; 5 x 4 = 20 elements fit, 24 not.
    EXPECT_EQ(choose_block(28, 20, 5), 4);
    EXPECT_EQ(choose_block(28, 24, 5), 0);
    for (std::int64_t g : {3 * two31, 9 * (two31 / 4), two31 * 5 * 7}) {
        const std::int64_t b = choose_block(g, g, INT_MAX);
        EXPECT_GT(b, 0);
        EXPECT_EQ(g % b, 0);
        EXPECT_LE(b, INT_MAX);
        EXPECT_LE(g / b, INT_MAX);
    }
}

// Rank r contributes 6 (r + 1) values (whole "layers" of 6): Allgatherv in blocks of the gcd 6
// when the limit (6) is below the largest count, and in elements otherwise, gathers the same.
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
    for (std::int64_t limit : {std::int64_t{INT_MAX}, std::int64_t{6}}) {
        const BlockCounts bc(MPI_COMM_WORLD, counts, displs, MPI_DOUBLE, {static_cast<std::int64_t>(mine.size())}, limit);
        EXPECT_EQ(bc.block(), limit == 6 && size > 1 ? 6 : 1);
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

// A ring of messages of n doubles: sent as one derived element (limit 3: chunks of 3 and the
// rest) and received as n doubles, and the other way round; the receiver counts n elements.
TEST(MpiCounts, LargeCountMessagesMatchPlainOnes) {
    const int rank = test::world_rank(), size = test::world_size();
    const int next = (rank + 1) % size, prev = (rank + size - 1) % size;
    for (std::int64_t n : {2, 6, 7}) {
        std::vector<double> send(static_cast<size_t>(n)), recv(send.size(), -1.0);
        std::iota(send.begin(), send.end(), 100.0 * rank);
        for (bool derived_send : {true, false}) {
            const LargeCount s(n, MPI_DOUBLE, derived_send ? 3 : INT_MAX), r(n, MPI_DOUBLE, derived_send ? INT_MAX : 3);
            EXPECT_EQ((derived_send ? s : r).count(), n > 3 ? 1 : n);
            MPI_Status st;
            MPI_Sendrecv(send.data(), s.count(), s.type(), next, 5, recv.data(), r.count(), r.type(), prev, 5,
                         MPI_COMM_WORLD, &st);
            MPI_Count got = 0;
            MPI_Get_elements_x(&st, r.type(), &got);
            EXPECT_EQ(got, n);
            for (std::int64_t e = 0; e < n; ++e)
                EXPECT_EQ(recv[static_cast<size_t>(e)], 100.0 * prev + static_cast<double>(e)) << "n " << n;
        }
    }
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
