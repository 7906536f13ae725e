// Render load balance (src/render/balance.h).
//  * balanced_split (pure): partitions, at least one layer per part, all-zero -> even split,
//    a spike forces one-layer parts, and on random weights the largest part is within the
//    largest layer weight of the brute-force optimal bottleneck (which is >= the mean).
//  * march_work_per_layer (pure): the footprint weight 1/(r² cos³θ) per occupied block: on
//    the optical axis a block twice as far weighs 1/4; blocks behind the camera weigh 0.
//  * balance_view_volume (MPI): on a bottom-heavy cloud the new boxes partition the domain,
//    the split moves (2 ranks), and every value of the moved volume, ghost layers included,
//    equals the view volume built for the whole medium on MPI_COMM_SELF, bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "src/core/error.h"
#include "src/render/balance.h"
#include "tests/support/mpi_test.h"
#include "tests/unit/render/render_fixture.h"

namespace nimbus {
namespace {

std::vector<double> part_sums(const std::vector<double>& w, const std::vector<int>& cut) {
    std::vector<double> s;
    for (size_t p = 0; p + 1 < cut.size(); ++p) {
        s.push_back(0.0);
        for (int k = cut[p]; k < cut[p + 1]; ++k) s.back() += w[static_cast<size_t>(k)];
    }
    return s;
}

void expect_partition(const std::vector<int>& cut, int n, int parts) {
    ASSERT_EQ(cut.size(), static_cast<size_t>(parts) + 1);
    EXPECT_EQ(cut.front(), 0);
    EXPECT_EQ(cut.back(), n);
    for (int p = 0; p < parts; ++p) EXPECT_GE(cut[static_cast<size_t>(p) + 1] - cut[static_cast<size_t>(p)], 1);
}

TEST(RenderBalance, UniformWeightsSplitEvenly) {
    const std::vector<double> w(10, 2.0);
    EXPECT_EQ(balanced_split(w, 2), (std::vector<int>{0, 5, 10}));
    EXPECT_EQ(balanced_split(w, 5), (std::vector<int>{0, 2, 4, 6, 8, 10}));
    EXPECT_EQ(balanced_split(w, 1), (std::vector<int>{0, 10}));
}

TEST(RenderBalance, AllZeroWeightsSplitLikeTheDecomposition) {
    const std::vector<double> w(7, 0.0);
    EXPECT_EQ(balanced_split(w, 3), (std::vector<int>{0, 2, 4, 7}));
}

TEST(RenderBalance, SpikeLeavesOneLayerParts) {
    const std::vector<double> w{9.0, 0.0, 0.0, 0.0, 0.0};
    const auto cut = balanced_split(w, 3);
    EXPECT_EQ(cut, (std::vector<int>{0, 1, 2, 5}));
    EXPECT_THROW(balanced_split(w, 6), Error);
}

TEST(RenderBalance, BottomHeavyCloudMovesTheCut) {
    // Work falling off with height like the cumulus' base: w_k = (n - k)².
    const int n = 64;
    std::vector<double> w(n);
    for (int k = 0; k < n; ++k) w[static_cast<size_t>(k)] = double(n - k) * (n - k);
    const auto cut = balanced_split(w, 2);
    expect_partition(cut, n, 2);
    // Prefix fraction 1 - (1 - x)³ = 1/2 at x = 1 - 2^{-1/3} = 0.2063: layer 13.2.
    EXPECT_NEAR(cut[1], 13, 1);
    const auto s = part_sums(w, cut);
    EXPECT_LE(std::abs(s[0] - s[1]), 2 * w[0]);
}

// Brute-force optimal bottleneck over every split of n layers into 3 parts.
double optimal_bottleneck(const std::vector<double>& w) {
    const int n = static_cast<int>(w.size());
    double best = 1e300;
    for (int a = 1; a < n - 1; ++a)
        for (int b = a + 1; b < n; ++b) {
            const auto s = part_sums(w, {0, a, b, n});
            best = std::min(best, *std::max_element(s.begin(), s.end()));
        }
    return best;
}

TEST(RenderBalance, RandomWeightsWithinOneLayerOfOptimal) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        const int n = 6 + trial % 20;
        std::vector<double> w(static_cast<size_t>(n));
        for (auto& x : w) x = 0.5 + u(rng);
        const auto cut = balanced_split(w, 3);
        expect_partition(cut, n, 3);
        const auto s = part_sums(w, cut);
        const double worst = *std::max_element(s.begin(), s.end());
        const double w_max = *std::max_element(w.begin(), w.end());
        EXPECT_LE(worst, optimal_bottleneck(w) + w_max) << "trial " << trial;
    }
}

TEST(RenderBalance, FootprintWeightFallsAsInverseSquareOnAxis) {
    // 8 x 8 x 32 cells of 1 m: four 8³ blocks stacked along z, camera on the z axis below,
    // looking up through the block centres at z = 4, 12, 20, 28 (distances 8, 16, 24, 32).
    Scene s;
    s.camera.domain_units = false;
    s.camera.position = {4, 4, -4};
    s.camera.look_at = {4, 4, 10};
    s.camera.up = {0, 1, 0};
    s.camera.fov_deg = 90;
    s.camera.width = s.camera.height = 64;
    ViewVolume v;
    v.grid.n = {8, 8, 32};
    v.grid.h = 1.0;
    v.owned = v.grid.box();
    v.nblocks = {1, 1, 4};
    v.occupied = {1, 1, 0, 1};
    const Camera cam(s.camera, v.grid);
    const auto work = march_work_per_layer(v, cam);
    ASSERT_EQ(work.size(), 32u);
    const double near = work[0];
    EXPECT_NEAR(near, 64.0 / (8.0 * 8.0), 1e-12);  // one layer: 64 cells / r², cos θ = 1
    for (int k = 0; k < 8; ++k) EXPECT_DOUBLE_EQ(work[static_cast<size_t>(k)], near);
    EXPECT_NEAR(work[8], near / 4, 1e-12);
    EXPECT_EQ(work[16], 0.0);  // empty block
    EXPECT_NEAR(work[24], near / 16, 1e-12);
    // Turned around, every block is behind the camera and weighs nothing.
    s.camera.look_at = {4, 4, -10};
    const auto behind = march_work_per_layer(v, Camera(s.camera, v.grid));
    for (double x : behind) EXPECT_EQ(x, 0.0);
}

TEST(RenderBalance, MovedVolumeEqualsTheWholeVolume) {
    Scene s;
    s.grid.n = {20, 16, 40};
    s.grid.cell_size = 0.25;
    s.bands = {BandOptics{"r", 0.6, 0.9, 0.8}, BandOptics{"g", 0.8, 0.92, 0.7},
               BandOptics{"b", 1.0, 0.95, 0.6}};
    s.render.mode = RenderMode::emission_absorption;
    s.render.emission_color = {0.5, 0.6, 0.7};
    s.camera.position = {0.5, -1.5, 0.3};
    s.camera.look_at = {0.5, 0.5, 0.3};
    s.camera.width = 48;
    s.camera.height = 32;
    const Grid g = make_grid(s.grid);
    // Dense base in k < 12, one small puff near the top: the work sits in the bottom third.
    auto rho = [&](int i, int j, int k) {
        if (!test::inside_domain(g.n, i, j, k)) return 0.0;
        if (k < 12 && i > 2 && i < 17 && j > 1 && j < 14) return 1.0 + 0.1 * i + 0.05 * j + 0.02 * k;
        if (k >= 30 && k < 33 && i >= 8 && i < 11 && j >= 6 && j < 9) return 0.5;
        return 0.0;
    };
    const auto world = test::make_world(MPI_COMM_WORLD, g, s, rho);
    const auto self = test::make_world(MPI_COMM_SELF, g, s, rho);
    const Camera cam(s.camera, g);
    const RenderInputs in_world{s, world.medium, world.light, world.diffuse};
    const RenderInputs in_self{s, self.medium, self.light, self.diffuse};
    const ViewVolume whole = build_view_volume(in_self, *self.d, cam.position());
    const ViewVolume v = balance_view_volume(build_view_volume(in_world, *world.d, cam.position()),
                                             *world.d, cam);

    // The new boxes tile the domain in rank order along z; x and y are whole.
    const int nranks = test::world_size(), rank = test::world_rank();
    std::vector<int> z(2 * static_cast<size_t>(nranks));
    const int mine[2] = {v.owned.lo[2], v.owned.hi[2]};
    MPI_Allgather(mine, 2, MPI_INT, z.data(), 2, MPI_INT, MPI_COMM_WORLD);
    EXPECT_EQ(z.front(), 0);
    EXPECT_EQ(z.back(), g.n[2]);
    for (int p = 0; p + 1 < nranks; ++p) EXPECT_EQ(z[2 * static_cast<size_t>(p) + 1], z[2 * static_cast<size_t>(p) + 2]);
    for (int a = 0; a < 2; ++a) {
        EXPECT_EQ(v.owned.lo[a], 0);
        EXPECT_EQ(v.owned.hi[a], g.n[a]);
    }
    if (nranks == 2) {
        EXPECT_LT(z[1], 16) << "the split follows the work down to the dense base";
    }

    ASSERT_EQ(v.data.allocated(), v.owned.grown(1));
    long mismatches = 0;
    for_each_cell(v.data.allocated(), [&](int i, int j, int k) {
        for (int c = 0; c < v.data.ncomp(); ++c) mismatches += v.data(i, j, k, c) != whole.data(i, j, k, c);
    });
    EXPECT_EQ(mismatches, 0) << "rank " << rank;
    // Occupancy rebuilt on the new box: every cell with density lies in an occupied block.
    long uncovered = 0;
    for_each_cell(v.owned, [&](int i, int j, int k) {
        uncovered += v.data(i, j, k, 0) > 0.0f && !v.occupied[static_cast<size_t>(v.block_index(i, j, k))];
    });
    EXPECT_EQ(uncovered, 0);
}

}  // namespace
}  // namespace nimbus
