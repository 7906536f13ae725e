// Decomposition: boxes partition the grid, slabs along z by default, clear refusals.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <string>

#include "src/core/decomposition.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

TEST(Decomposition, DefaultIsSlabsAlongZAndBoxesPartitionTheGrid) {
    const Decomposition d(MPI_COMM_WORLD, {10, 7, 9});
    EXPECT_TRUE(d.is_slab_z());
    EXPECT_EQ(d.dims()[2], test::world_size());
    std::int64_t total = 0;
    for (int r = 0; r < d.size(); ++r) {
        const Box b = d.box_of(r);
        EXPECT_EQ(b.size(0), 10);
        EXPECT_EQ(b.size(1), 7);
        total += b.cells();
        for (int q = r + 1; q < d.size(); ++q) EXPECT_TRUE(b.intersect(d.box_of(q)).empty());
    }
    EXPECT_EQ(total, 10 * 7 * 9);
    EXPECT_EQ(d.local(), d.box_of(d.rank()));
}

// A planned decomposition (info --ranks) is the one the ranks build: same process grid, and for
// every rank the same coordinates (MPI_Cart_coords against row-major arithmetic) and box.
TEST(Decomposition, PlanEqualsTheRanksDecomposition) {
    const int P = test::world_size();
    const Int3 n{11, 10, 9};
    for (const Int3 pg : {Int3{0, 0, 0}, Int3{P, 1, 1}, Int3{1, P, 1}, Int3{1, 1, 0}}) {
        const Decomposition real(MPI_COMM_WORLD, n, pg, {true, false, false});
        for (int r = 0; r < P; ++r) {
            const Decomposition plan = Decomposition::plan(n, P, pg, {true, false, false}, r);
            EXPECT_EQ(plan.dims(), real.dims());
            EXPECT_EQ(plan.local(), real.box_of(r));
            EXPECT_EQ(plan.size(), P);
            EXPECT_TRUE(plan.periodic(0));
            if (r == real.rank()) {
                EXPECT_EQ(plan.coords(), real.coords());  // real's from MPI_Cart_coords
            }
        }
    }
}

// Planning for more ranks than are running: boxes of every rank partition the grid, and the
// refusals are the constructor's, naming --ranks.
TEST(Decomposition, PlanForManyRanksPartitionsTheGrid) {
    const Int3 n{40, 30, 20};
    for (const Int3 pg : {Int3{0, 0, 0}, Int3{2, 0, 0}, Int3{3, 2, 2}}) {
        const Decomposition d = Decomposition::plan(n, 12, pg);
        EXPECT_EQ(d.dims()[0] * d.dims()[1] * d.dims()[2], 12);
        std::int64_t total = 0;
        for (int r = 0; r < 12; ++r) {
            const Box b = d.box_of(r);
            total += b.cells();
            for (int q = r + 1; q < 12; ++q) EXPECT_TRUE(b.intersect(d.box_of(q)).empty()) << r << " " << q;
        }
        EXPECT_EQ(total, 40 * 30 * 20);
    }
    EXPECT_EQ(Decomposition::plan(n, 12).comm(), MPI_COMM_NULL);
    try {
        Decomposition::plan(n, 4, {3, 1, 1});
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(), "process grid 3x1x1 needs 3 ranks, not the 4 of --ranks");
    }
    EXPECT_THROW(Decomposition::plan(n, 21), Error);  // 21 slabs of a 20-layer grid
    EXPECT_THROW(Decomposition::plan(n, 4, {0, 0, 0}, {false, false, false}, 4), Error);  // no rank 4
}

TEST(Decomposition, RefusesRanksWithoutCells) {
    // One z layer cannot be split over 2 ranks; on 1 rank the grid is fine.
    if (test::world_size() == 1) {
        EXPECT_NO_THROW(Decomposition(MPI_COMM_WORLD, {4, 4, 1}));
    } else {
        try {
            Decomposition d(MPI_COMM_WORLD, {4, 4, 1});
            FAIL() << "expected an Error";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("no cells"), std::string::npos) << e.what();
        }
    }
}

TEST(Decomposition, RefusesZeroSizeGridAndBadProcessGrid) {
    EXPECT_THROW(Decomposition(MPI_COMM_WORLD, {0, 4, 4}), Error);
    // A process grid whose product is not the rank count.
    EXPECT_THROW(Decomposition(MPI_COMM_WORLD, {4, 4, 4}, {test::world_size() + 1, 1, 1}), Error);
    // Fixed entries that do not divide the rank count: the message says which, not "2x0x0".
    const int fixed = test::world_size() + 1;
    try {
        Decomposition(MPI_COMM_WORLD, {8, 8, 8}, {fixed, 0, 0});
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()),
                  fmt::format("process grid [{}, 0, 0]: the fixed entries (product {}) do not divide the {} ranks "
                              "(0 = chosen to fit)",
                              fixed, fixed, test::world_size()));
    }
}

TEST(Decomposition, ProcessGridAlongXIsAllowed) {
    const Decomposition d(MPI_COMM_WORLD, {8, 4, 4}, {test::world_size(), 1, 1});
    EXPECT_EQ(d.dims()[0], test::world_size());
    // 8 cells over P ranks: each rank gets floor(8/P) or one more, and together all 8.
    const int mine = d.local().size(0), P = test::world_size();
    EXPECT_GE(mine, 8 / P);
    EXPECT_LE(mine, (8 + P - 1) / P);
    int total = 0;
    MPI_Allreduce(&mine, &total, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(total, 8);
}

}  // namespace
}  // namespace nimbus
