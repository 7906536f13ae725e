// sweep::run_octants (solvers/sweep/sweep.h): octants swept concurrently with data-driven
// scheduling. Kernel: a known recurrence psi_c = (c + 1) + 0.5 Σ_axes psi_c(upwind) (with 0 at
// the domain boundary), whose result depends on every upwind value being final. Checked
// against a serial triple loop on the whole grid (bit for bit: same operations, same order)
// and against run() octant by octant, for the +z/-z pairs and for all 8 octants at once, with
// many and with few tiles (tile_rows 1, 3, 100), on a z-slab chain and on an x process grid.
#include <gtest/gtest.h>

#include <vector>

#include "solvers/sweep/sweep.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

constexpr int kComp = 2;

sweep::Octant octant(int oct) { return {{oct & 1 ? 1 : -1, oct & 2 ? 1 : -1, oct & 4 ? 1 : -1}}; }

void recurrence(Field<double>& psi, const sweep::Octant& o, int i, int j, int k) {
    for (int c = 0; c < kComp; ++c)
        psi(i, j, k, c) =
            (c + 1) + 0.5 * (psi(i - o.s[0], j, k, c) + psi(i, j - o.s[1], k, c) + psi(i, j, k - o.s[2], c));
}

// Serial reference of one octant on the whole grid.
Field<double> serial(const Int3& n, const sweep::Octant& o) {
    Field<double> ref(Box{{0, 0, 0}, n}, 1, kComp, 0.0);
    const auto rx = sweep::upwind_range(ref.owned(), 0, o), ry = sweep::upwind_range(ref.owned(), 1, o),
               rz = sweep::upwind_range(ref.owned(), 2, o);
    for (int k = rz.first; k != rz.end; k += rz.step)
        for (int j = ry.first; j != ry.end; j += ry.step)
            for (int i = rx.first; i != rx.end; i += rx.step) recurrence(ref, o, i, j, k);
    return ref;
}

// Sweeps the octants `group` concurrently and checks each against the serial reference and
// against run() of that octant alone.
void check_group(const Decomposition& d, const Int3& n, const std::vector<int>& group, int tile_rows) {
    sweep::SweepOptions opt;
    opt.tile_rows = tile_rows;
    std::vector<Field<double>> fields;
    std::vector<sweep::Octant> octants;
    for (int oct : group) {
        fields.emplace_back(d.local(), 1, kComp, 0.0);
        octants.push_back(octant(oct));
    }
    std::vector<Field<double>*> psi;
    for (auto& f : fields) psi.push_back(&f);
    const sweep::SweepStats stats = sweep::run_octants(d, psi, octants, opt, [&](int q, int i, int j, int k) {
        recurrence(*psi[static_cast<size_t>(q)], octants[static_cast<size_t>(q)], i, j, k);
    });
    const int ny = d.local().size(1);
    const int tiles = d.dims()[1] == 1 ? (ny + std::min(tile_rows, ny) - 1) / std::min(tile_rows, ny) : 1;
    EXPECT_EQ(stats.tiles, static_cast<int>(group.size()) * tiles);
    for (size_t q = 0; q < group.size(); ++q) {
        const sweep::Octant& o = octants[q];
        const Field<double> ref = serial(n, o);
        Field<double> alone(d.local(), 1, kComp, 0.0);
        sweep::run(d, alone, o, opt, [&](int i, int j, int k) { recurrence(alone, o, i, j, k); });
        for_each_cell(d.local(), [&](int i, int j, int k) {
            for (int c = 0; c < kComp; ++c) {
                ASSERT_EQ(fields[q](i, j, k, c), ref(i, j, k, c))
                    << "octant " << group[q] << " tile_rows " << tile_rows << " at " << i << "," << j << "," << k;
                ASSERT_EQ(fields[q](i, j, k, c), alone(i, j, k, c)) << "octant " << group[q];
            }
        });
    }
}

TEST(SweepEngine, PairsOfOppositeZOctantsMatchTheSerialRecurrence) {
    const Int3 n{5, 7, 6};
    const Decomposition d(MPI_COMM_WORLD, n);
    for (int tile_rows : {1, 3, 100})
        for (int xy = 0; xy < 4; ++xy) check_group(d, n, {xy, xy | 4}, tile_rows);
}

TEST(SweepEngine, AllEightOctantsMatchTheSerialRecurrence) {
    const Int3 n{4, 6, 8};
    const Decomposition d(MPI_COMM_WORLD, n);
    for (int tile_rows : {1, 3, 100}) check_group(d, n, {0, 1, 2, 3, 4, 5, 6, 7}, tile_rows);
}

TEST(SweepEngine, AllEightOctantsOnAProcessGridAlongX) {
    const Int3 n{8, 5, 4};
    const Decomposition d(MPI_COMM_WORLD, n, {test::world_size(), 1, 1});
    check_group(d, n, {0, 1, 2, 3, 4, 5, 6, 7}, 2);
}

TEST(SweepEngine, OneOctantEqualsRun) {
    const Int3 n{6, 5, 7};
    const Decomposition d(MPI_COMM_WORLD, n);
    for (int oct = 0; oct < 8; ++oct) check_group(d, n, {oct}, 2);
}

// More octants than have message tags (their tags would reach LPM's 950): Error on every rank,
// before any message (a rank left in MPI would hang the test).
TEST(SweepEngine, MoreThanEightOctantsThrow) {
    const Int3 n{4, 4, 4};
    const Decomposition d(MPI_COMM_WORLD, n);
    std::vector<Field<double>> fields;
    std::vector<sweep::Octant> octants;
    for (int q = 0; q <= sweep::kMaxOctants; ++q) {
        fields.emplace_back(d.local(), 1, kComp, 0.0);
        octants.push_back(octant(q % 8));
    }
    std::vector<Field<double>*> psi;
    for (auto& f : fields) psi.push_back(&f);
    EXPECT_THROW(sweep::run_octants(d, psi, octants, sweep::SweepOptions{}, [](int, int, int, int) {}), Error);
}

}  // namespace
}  // namespace nimbus
