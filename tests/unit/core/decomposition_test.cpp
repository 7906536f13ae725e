// Decomposition: boxes partition the grid, slabs along z by default, clear refusals.
#include <gtest/gtest.h>

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
