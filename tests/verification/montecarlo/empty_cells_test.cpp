// The Monte Carlo's fluence in empty cells (MonteCarloOptions::empty_cells; DESIGN defines
// fluence_diffuse there too, and without the option it stays 0):
//   (a) one emitting cell in vacuum: the cell-averaged fluence of the empty cells around it is
//       P / (4π r²) integrated over the two cells (point_source_fluence), z-test per detector;
//   (b) a thin cell lit by an overhead sun, g = 0, every photon forced to scatter: the light it
//       scatters falls off in the empty cells as the same point source of the power that
//       escapes (the counters), z-test per detector;
//   (c) a periodic slab between empty layers: every path that crosses the empty layers below
//       (above) crosses all of them, a track of h / |w_z| in each, so their totals are equal to
//       round-off: a cell missed or counted twice by the walk, or a wrap gone wrong, breaks it;
//   (d) the option changes nothing else: with and without it the same collisions, counters
//       and fluence in the cells with density; the same fields on 1 rank and on all, and with
//       the scalar and the lane kernel.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

#include "solvers/montecarlo/forward.h"
#include "solvers/montecarlo/trace_lanes.h"
#include "src/scene/emission.h"
#include "tests/support/mpi_test.h"
#include "tests/support/point_source.h"

namespace nimbus::mc {
namespace {

// An n³ domain of cells of edge h, density 1 in `cells` only (no periodic axes unless asked).
struct Sparse {
    Decomposition d;
    Medium m;
    Sparse(MPI_Comm comm, Int3 n, double h, BandOptics optics, const Box& cells,
           std::array<bool, 3> periodic = {false, false, false})
        : d(comm, n, {0, 0, 0}, periodic) {
        m.grid.n = n;
        m.grid.h = h;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(cells.intersect(d.local()), [&](int i, int j, int k) { m.rho(i, j, k) = 1.0; });
        m.bands = {optics};
    }
};

MonteCarloOptions options(std::int64_t photons, bool empty_cells, std::uint64_t seed = 13) {
    MonteCarloOptions o;
    o.photons = photons;
    o.seed = seed;
    o.batches = 32;
    o.empty_cells = empty_cells;
    return o;
}

// Band 0's fluence and standard error at global cell q (every rank gets them).
std::array<double, 2> at(const Decomposition& d, const ForwardResult& r, const Int3& q) {
    double v[2] = {0.0, 0.0};
    if (d.local().contains(q[0], q[1], q[2])) v[0] = r.fluence[0](q[0], q[1], q[2]), v[1] = r.fluence_stderr[0](q[0], q[1], q[2]);
    MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_SUM, d.comm());
    return {v[0], v[1]};
}

// Detectors in the empty cells around the cell (7, 7, 7): on the axes, diagonals, both sides.
const std::vector<Int3> kDetectors = {{9, 7, 7},  {10, 7, 7}, {12, 7, 7},  {7, 4, 7},  {7, 7, 2},   {7, 7, 11},
                                      {9, 9, 7},  {5, 5, 5},  {10, 10, 10}, {5, 9, 11}, {3, 3, 12}, {13, 2, 7}};

// z = (MC - exact) / stderr per detector: rms within [0.5, 1.6] and none beyond 4 (12 detectors;
// chi-square with 12 degrees of freedom puts 99% of rms values above 0.55).
void expect_point_source(const Decomposition& d, const ForwardResult& r, double power, const char* what) {
    double z2 = 0.0, zmax = 0.0;
    for (const Int3& q : kDetectors) {
        const auto [v, se] = at(d, r, q);
        const double exact =
            test::point_source_fluence({7, 7, 7}, {double(q[0]), double(q[1]), double(q[2])}, 1.0, 0.0, power);
        const double z = (v - exact) / se;
        if (test::world_rank() == 0)
            std::printf("%s: cell (%d,%d,%d): MC %.5e ± %.1e, exact %.5e (rel %+.4f, z %+.2f)\n", what, q[0], q[1],
                        q[2], v, se, exact, v / exact - 1.0, z);
        z2 += z * z;
        zmax = std::max(zmax, std::abs(z));
    }
    const double rms = std::sqrt(z2 / static_cast<double>(kDetectors.size()));
    if (test::world_rank() == 0) std::printf("%s: rms z %.2f, max |z| %.2f\n", what, rms, zmax);
    EXPECT_GT(rms, 0.5) << what;
    EXPECT_LT(rms, 1.6) << what;
    EXPECT_LT(zmax, 4.0) << what;
}

TEST(EmptyCells, PointSourceInVacuum) {
    // 15³ cells of 1 m; only the emitting cell (7, 7, 7) has density (kappa 1e-5 /m: the
    // light leaves it with 1 - 1e-5 of its power); 5 W/m³ there, P = 5 W.
    const double p = 5.0;
    const Box cell{{7, 7, 7}, {8, 8, 8}};
    Sparse s(MPI_COMM_WORLD, {15, 15, 15}, 1.0, BandOptics{"gray", 1e-5, 0.0, 0.0}, cell);
    const std::vector<VolumeSource> src{{cell, {p}}};
    const ForwardResult r = trace_forward(s.d, s.m, {}, src, options(400000, true));
    expect_point_source(s.d, r, p, "point source in vacuum");
    // Without the option the empty cells keep 0.
    const ForwardResult off = trace_forward(s.d, s.m, {}, src, options(20000, false));
    for (const Int3& q : kDetectors) EXPECT_EQ(at(s.d, off, q)[0], 0.0);
}

TEST(EmptyCells, LightScatteredByAThinCellFallsOffAsTheInverseSquare) {
    // The cell (7, 7, 7) of 15³ cells of 1 m, kappa h = 0.005, albedo 1, g = 0, under an
    // overhead sun of 1 W/m²: every photon enters its top and is forced to scatter (weight
    // 1 - e^-0.005). The single-scatter source is uniform in the cell to 0.5% and its escape
    // isotropic to about as much; second scatters take 0.5% of the power and are counted in
    // the escaped power, the point source's P.
    const Box cell{{7, 7, 7}, {8, 8, 8}};
    Sparse s(MPI_COMM_WORLD, {15, 15, 15}, 1.0, BandOptics{"gray", 0.005, 1.0, 0.0}, cell);
    const std::vector<DirectionalLight> sun{{"sun", {0.0, 0.0, -1.0}, {1.0}}};
    ForwardSettings forced;
    forced.forced_first_collision = true;
    MonteCarloOptions opt = options(1000000, true);
    opt.roulette_weight = 1e-3;  // below the weight 0.005: no roulette, no noise in the power
    const ForwardResult r = trace_forward(s.d, s.m, sun, {}, opt, forced);
    const Counters& c = r.counters[0];
    double scattered = 0.0;
    for (int f = 0; f < 6; ++f) scattered += c[escaped_xlo + f];
    EXPECT_NEAR(scattered, -std::expm1(-0.005), 1e-9);  // albedo 1: all the forced weight leaves
    expect_point_source(s.d, r, scattered, "thin scattering cell");
}

// Totals of band 0's fluence per z layer (all ranks).
std::vector<double> layer_totals(const Decomposition& d, const ForwardResult& r, int nz) {
    std::vector<double> t(static_cast<size_t>(nz), 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) { t[static_cast<size_t>(k)] += r.fluence[0](i, j, k); });
    MPI_Allreduce(MPI_IN_PLACE, t.data(), nz, MPI_DOUBLE, MPI_SUM, d.comm());
    return t;
}

TEST(EmptyCells, EmptyLayersAroundAPeriodicSlabCarryEqualTotals) {
    // 7 x 6 x 20 cells, periodic in x and y, density in layers 6..13 (kappa h = 0.4, a 0.9,
    // g 0.6), under an oblique sun (wraps in x and y): layers 0..5 and 14..19 are empty.
    const int nz = 20;
    Sparse s(MPI_COMM_WORLD, {7, 6, nz}, 1.0, BandOptics{"gray", 0.4, 0.9, 0.6}, Box{{0, 0, 6}, {7, 6, 14}},
             {true, true, false});
    const std::vector<DirectionalLight> sun{{"sun", normalized(Vec3{0.5, 0.3, -0.7}), {1.0}}};
    const ForwardResult r = trace_forward(s.d, s.m, sun, {}, options(40000, true));
    const std::vector<double> t = layer_totals(s.d, r, nz);
    for (const auto& [lo, hi] : {std::array<int, 2>{0, 6}, std::array<int, 2>{14, 20}}) {
        EXPECT_GT(t[static_cast<size_t>(lo)], 0.0);
        for (int k = lo + 1; k < hi; ++k)
            EXPECT_NEAR(t[static_cast<size_t>(k)], t[static_cast<size_t>(lo)], 1e-10 * t[static_cast<size_t>(lo)])
                << "empty layer " << k << " against layer " << lo;
    }
    // Horizontal homogeneity: the cells of an empty layer agree with its mean to within 5
    // standard errors (the paths' exits are uniform over the periodic plane).
    for_each_cell(s.d.local(), [&](int i, int j, int k) {
        if (k >= 6 && k < 14) return;
        const double mean = t[static_cast<size_t>(k)] / 42.0;
        EXPECT_LT(std::abs(r.fluence[0](i, j, k) - mean), 5.0 * r.fluence_stderr[0](i, j, k) + 1e-12 * mean)
            << i << " " << j << " " << k;
    });
}

// A cloud with holes inside a larger empty domain, a sun and a source: with and without the
// empty cells' tallies, the same paths.
struct Holey {
    Decomposition d;
    Medium m;
    explicit Holey(MPI_Comm comm) : d(comm, {12, 10, 14}, {0, 0, 0}, {false, false, false}) {
        m.grid.n = {12, 10, 14};
        m.grid.h = 0.5;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(Box{{3, 2, 4}, {9, 8, 11}}.intersect(d.local()), [&](int i, int j, int k) {
            m.rho(i, j, k) = (i + 2 * j + k) % 5 == 0 ? 0.0 : 0.6 + 0.1 * (k % 3);
        });
        m.bands = {BandOptics{"gray", 1.3, 0.9, 0.7}};
    }
};

TEST(EmptyCells, ChangeNothingInTheMediumAndMatchOnAnyRankCountAndKernel) {
    const std::vector<DirectionalLight> L{{"sun", normalized(Vec3{0.2, -0.4, -0.8}), {1.0}}};
    const std::vector<VolumeSource> src{{Box{{4, 3, 5}, {7, 6, 8}}, {0.5}}};
    Holey world(MPI_COMM_WORLD), self(MPI_COMM_SELF);
    const ForwardResult off = trace_forward(world.d, world.m, L, src, options(12000, false));
    const ForwardResult on = trace_forward(world.d, world.m, L, src, options(12000, true));
    const ForwardResult one = trace_forward(self.d, self.m, L, src, options(12000, true));
    EXPECT_EQ(on.collisions, off.collisions);
    EXPECT_GT(on.segments, off.segments);
    const double scale = off.counters[0][incident] + off.counters[0][emitted];
    for (int q = 0; q < ncounters; ++q) {
        EXPECT_NEAR(on.counters[0][q], off.counters[0][q], 1e-12 * scale) << "counter " << q;
        EXPECT_NEAR(on.counters[0][q], one.counters[0][q], 1e-12 * scale) << "counter " << q;
    }
    double peak = 0.0, medium = 0.0, ranks = 0.0;
    std::int64_t empty = 0, lit = 0;
    for_each_cell(world.d.local(), [&](int i, int j, int k) {
        const double v = on.fluence[0](i, j, k);
        peak = std::max(peak, v);
        ranks = std::max({ranks, std::abs(v - one.fluence[0](i, j, k)),
                          std::abs(on.fluence_stderr[0](i, j, k) - one.fluence_stderr[0](i, j, k))});
        if (world.m.rho(i, j, k) > 0) {
            medium = std::max(medium, std::abs(v - off.fluence[0](i, j, k)));
            return;
        }
        EXPECT_EQ(off.fluence[0](i, j, k), 0.0);
        ++empty;
        lit += v > 0.0;
    });
    MPI_Allreduce(MPI_IN_PLACE, &peak, 1, MPI_DOUBLE, MPI_MAX, world.d.comm());
    double worst[2] = {medium, ranks};
    MPI_Allreduce(MPI_IN_PLACE, worst, 2, MPI_DOUBLE, MPI_MAX, world.d.comm());
    std::int64_t counts[2] = {empty, lit};
    MPI_Allreduce(MPI_IN_PLACE, counts, 2, MPI_INT64_T, MPI_SUM, world.d.comm());
    EXPECT_LT(worst[0], 1e-12 * peak);  // the medium's cells: as without the option
    EXPECT_LT(worst[1], 1e-12 * peak);  // 1 rank: the same fields everywhere
    EXPECT_GT(counts[1], counts[0] * 9 / 10);  // nearly every empty cell sees diffuse light
    if (!lane_kernel_supported()) return;
    MonteCarloOptions scalar = options(12000, true), lanes = options(12000, true);
    scalar.kernel = "scalar";
    lanes.kernel = "lanes";
    const ForwardResult a = trace_forward(world.d, world.m, L, src, scalar);
    const ForwardResult b = trace_forward(world.d, world.m, L, src, lanes);
    double kernels = 0.0;
    for_each_cell(world.d.local(), [&](int i, int j, int k) {
        kernels = std::max(kernels, std::abs(a.fluence[0](i, j, k) - b.fluence[0](i, j, k)));
    });
    MPI_Allreduce(MPI_IN_PLACE, &kernels, 1, MPI_DOUBLE, MPI_MAX, world.d.comm());
    EXPECT_LT(kernels, 1e-12 * peak);
}

}  // namespace
}  // namespace nimbus::mc
