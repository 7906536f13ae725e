// Halo exchange fills every ghost inside the domain (faces, edges, corners) with the owner's
// value, wraps periodic axes, and leaves ghosts outside a closed domain untouched.
#include <gtest/gtest.h>

#include "src/core/halo.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

double code(int i, int j, int k) { return i + 100.0 * j + 10000.0 * k; }

void check_halo(const Int3& dims, std::array<bool, 3> periodic) {
    const Int3 n{6, 5, 8};
    const Decomposition d(MPI_COMM_WORLD, n, dims, periodic);
    Field<double> f(d.local(), 2, 2, -1.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        f(i, j, k, 0) = code(i, j, k);
        f(i, j, k, 1) = -code(i, j, k);
    });
    exchange_halo(f, d);
    for_each_cell(f.allocated(), [&](int i, int j, int k) {
        int g[3] = {i, j, k};
        bool inside = true;
        for (int a = 0; a < 3; ++a) {
            if (periodic[a]) g[a] = (g[a] % n[a] + n[a]) % n[a];
            inside = inside && g[a] >= 0 && g[a] < n[a];
        }
        const double want = inside ? code(g[0], g[1], g[2]) : -1.0;
        ASSERT_EQ(f(i, j, k, 0), want) << i << "," << j << "," << k;
        ASSERT_EQ(f(i, j, k, 1), inside ? -want : -1.0);
    });
}

TEST(Halo, SlabsAlongZ) { check_halo({1, 1, 0}, {false, false, false}); }
TEST(Halo, SlabsAlongX) { check_halo({0, 1, 1}, {false, false, false}); }
TEST(Halo, PeriodicXY) { check_halo({1, 1, 0}, {true, true, false}); }
TEST(Halo, PeriodicZAcrossRanks) { check_halo({1, 1, 0}, {false, false, true}); }

}  // namespace
}  // namespace nimbus
