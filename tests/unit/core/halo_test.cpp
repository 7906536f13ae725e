// Halo exchange fills every ghost inside the domain (faces, edges, corners) with the owner's
// value, wraps periodic axes, and leaves ghosts outside a closed domain untouched.
#include <gtest/gtest.h>

#include <string>

#include "src/core/error.h"
#include "src/core/halo.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

double code(int i, int j, int k) { return i + 100.0 * j + 10000.0 * k; }

// Whether ghost cell g is some rank's cell: g becomes that cell (wrapped along periodic axes).
bool owned_cell(Int3& g, const Int3& n, const std::array<bool, 3>& periodic) {
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
        if (periodic[static_cast<size_t>(a)]) g[a] = (g[a] % n[a] + n[a]) % n[a];
        inside = inside && g[a] >= 0 && g[a] < n[a];
    }
    return inside;
}

void check_halo(const Int3& dims, std::array<bool, 3> periodic, const Int3& n = {6, 5, 8}, int ghost = 2) {
    const Decomposition d(MPI_COMM_WORLD, n, dims, periodic);
    Field<double> f(d.local(), ghost, 2, -1.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        f(i, j, k, 0) = code(i, j, k);
        f(i, j, k, 1) = -code(i, j, k);
    });
    exchange_halo(f, d);
    for_each_cell(f.allocated(), [&](int i, int j, int k) {
        Int3 g{i, j, k};
        const bool inside = owned_cell(g, n, periodic);
        const double want = inside ? code(g[0], g[1], g[2]) : -1.0;
        ASSERT_EQ(f(i, j, k, 0), want) << i << "," << j << "," << k;
        ASSERT_EQ(f(i, j, k, 1), inside ? -want : -1.0);
    });
}

TEST(Halo, SlabsAlongZ) { check_halo({1, 1, 0}, {false, false, false}); }
TEST(Halo, SlabsAlongX) { check_halo({0, 1, 1}, {false, false, false}); }
TEST(Halo, PeriodicXY) { check_halo({1, 1, 0}, {true, true, false}); }
TEST(Halo, PeriodicZAcrossRanks) { check_halo({1, 1, 0}, {false, false, true}); }

// Ghosts come from the adjacent rank only: 3 ghost layers need boxes at least 3 cells thick.
// 5 z layers: one rank fills them; 2 or more ranks (boxes of 2 or fewer) are refused on every
// rank with the same error (a thicker rank used to send more layers than its neighbour
// expected: MPI_ERR_TRUNCATE, or misplaced ghosts).
TEST(Halo, GhostsDeeperThanTheThinnestBoxAreRefused) {
    const Int3 n{4, 3, 5};
    const Decomposition d(MPI_COMM_WORLD, n, {1, 1, 0});
    if (d.size() == 1) {
        check_halo({1, 1, 0}, {false, false, false}, n, 3);
        return;
    }
    Field<double> f(d.local(), 3, 1, 0.0);
    try {
        exchange_halo(f, d);
        ADD_FAILURE() << "no error for 3 ghost layers on boxes of " << d.thinnest(2) << " layers";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("needs every rank's box at least 3 cells thick along z"),
                  std::string::npos) << e.what();
    }
}

// A field on the rank's part of a box `within` (exchange_halo's third argument): every ghost
// inside `within` and the domain (or across a periodic wrap) gets the owner's value, the others
// keep theirs; ranks whose part is empty take part without exchanging. Boxes that end inside a
// rank, that miss whole ranks, and that span the grid; split along z or x; periodic or not.
void check_part_halo(const Int3& dims, std::array<bool, 3> periodic, const Box& within) {
    const Int3 n{7, 5, 9};
    const Decomposition d(MPI_COMM_WORLD, n, dims, periodic);
    Field<double> f(d.local().intersect(within), 1, 1, -1.0);
    for_each_cell(f.owned(), [&](int i, int j, int k) { f(i, j, k) = code(i, j, k); });
    exchange_halo(f, d, within);
    if (f.owned().empty()) return;  // no part here: its "ghosts" are nobody's neighbours
    for_each_cell(f.allocated(), [&](int i, int j, int k) {
        Int3 g{i, j, k};
        const bool filled = owned_cell(g, n, periodic) && within.contains(g[0], g[1], g[2]);
        ASSERT_EQ(f(i, j, k), filled ? code(g[0], g[1], g[2]) : -1.0) << i << "," << j << "," << k;
    });
}

TEST(Halo, PartsOfTheRanksBoxes) {
    const int size = test::world_size();
    const Box low{{1, 0, 0}, {6, 4, 3}};  // only the first rank's slab on 3 ranks along z
    const Box middle{{0, 1, 2}, {7, 5, 7}};
    const Box all{{0, 0, 0}, {7, 5, 9}};
    for (const Int3 dims : {Int3{1, 1, size}, Int3{size, 1, 1}}) {
        check_part_halo(dims, {false, false, false}, low);
        check_part_halo(dims, {false, false, false}, middle);
        check_part_halo(dims, {false, false, false}, all);
        check_part_halo(dims, {true, false, false}, middle.with_range(0, 0, 7));  // whole along periodic x
        check_part_halo(dims, {false, false, true}, middle.with_range(2, 0, 9));
    }
}

// A part that is not whole along a periodic axis is refused (the wrap would join its ends).
TEST(Halo, PartsMustBeWholeAlongPeriodicAxes) {
    const Decomposition d(MPI_COMM_WORLD, {7, 5, 9}, {1, 1, 0}, {true, false, false});
    const Box within{{1, 0, 0}, {6, 5, 9}};
    Field<double> f(d.local().intersect(within), 1, 1, 0.0);
    EXPECT_THROW(exchange_halo(f, d, within), Error);
}

// accumulate_halo along z: what each rank deposited in its z ghost layers lands, added, in the
// owners' boundary layers; ghosts outside the domain are dropped and every ghost ends at 0.
TEST(Halo, AccumulateAddsGhostDepositsIntoTheOwners) {
    const Int3 n{5, 4, 9};
    const Decomposition d(MPI_COMM_WORLD, n, {1, 1, 0});
    auto deposit = [](int q, int i, int j, int k) { return 1.0 + q + 0.01 * i + 1e-4 * j + 1e-6 * (k + 1); };
    Field<double> f(d.local(), 1, 1, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) { f(i, j, k) = 7.0; });
    const Box& own = d.local();
    for (int k : {own.lo[2] - 1, own.hi[2]})
        for (int j = own.lo[1] - 1; j <= own.hi[1]; ++j)
            for (int i = own.lo[0] - 1; i <= own.hi[0]; ++i) f(i, j, k) = deposit(d.rank(), i, j, k);
    accumulate_halo(f, d, 2);
    for_each_cell(f.allocated(), [&](int i, int j, int k) {
        double want = 0.0;
        if (own.contains(i, j, k)) {
            want = 7.0;
            for (int q = 0; q < d.size(); ++q) {  // rank q's ghost layers just below and above its box
                const Box b = d.box_of(q);
                if (q != d.rank() && (k == b.lo[2] - 1 || k == b.hi[2])) want += deposit(q, i, j, k);
            }
        }
        ASSERT_DOUBLE_EQ(f(i, j, k), want) << i << "," << j << "," << k;
    });
}

// Deeper ghosts across ranks whose boxes are thick enough (12 layers: boxes of 3 or more on up
// to 4 ranks), periodic z wrapping them.
TEST(Halo, ThreeGhostLayersAcrossRanks) {
    check_halo({1, 1, 0}, {false, false, true}, {4, 3, 12}, 3);
}

}  // namespace
}  // namespace nimbus
