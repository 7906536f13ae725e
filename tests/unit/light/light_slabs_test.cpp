// The exact light pass's balanced slabs (light_slabs.h): the cuts minimise the busiest slab's
// cost (against every possible cut), and the pilot's counts are those of the walk.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <numeric>
#include <random>

#include "solvers/light/light_slabs.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

// The smallest largest-slab cost over every cut of nz layers into `parts` slabs.
double best_by_enumeration(const ChainWork& w, int parts, double setup) {
    const int nz = static_cast<int>(w.steps.size());
    double best = std::numeric_limits<double>::infinity();
    std::vector<int> cuts{0};
    std::function<void(int)> place = [&](int lo) {
        if (static_cast<int>(cuts.size()) == parts) {
            cuts.push_back(nz);
            best = std::min(best, w.max_cost(cuts, setup));
            cuts.pop_back();
            return;
        }
        for (int c = lo + 1; c <= nz - (parts - static_cast<int>(cuts.size())); ++c) {
            cuts.push_back(c);
            place(c);
            cuts.pop_back();
        }
    };
    place(0);
    return best;
}

ChainWork random_work(std::mt19937& rng, int nz, bool toward_high_z) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    ChainWork w;
    w.toward_high_z = toward_high_z;
    for (int k = 0; k < nz; ++k) {
        w.steps.push_back(std::floor(1000 * u(rng) * u(rng)));
        w.starts.push_back(std::floor(50 * u(rng)));
    }
    // Rays entering face f from downstream: at most those that started there or crossed the
    // face before (what the pilot's geometry gives).
    w.entering.assign(static_cast<size_t>(nz) + 1, 0.0);
    if (toward_high_z) {
        for (int f = 1; f < nz; ++f)
            w.entering[f] = std::floor((w.entering[f - 1] + w.starts[f - 1]) * (0.7 + 0.3 * u(rng)));
    } else {
        for (int f = nz - 1; f >= 1; --f)
            w.entering[f] = std::floor((w.entering[f + 1] + w.starts[f]) * (0.7 + 0.3 * u(rng)));
    }
    return w;
}

TEST(LightSlabs, BalancedCutsAreOptimal) {
    std::mt19937 rng(7);
    for (int trial = 0; trial < 40; ++trial) {
        const int nz = 3 + trial % 9, parts = 1 + trial % std::min(nz, 4);
        const bool up = trial % 2 == 0;
        const double setup = trial % 3 == 0 ? 0.0 : 30.0;
        const ChainWork w = random_work(rng, nz, up);
        const std::vector<int> cuts = balanced_cuts(w, parts, setup);
        ASSERT_EQ(cuts.size(), static_cast<size_t>(parts) + 1);
        EXPECT_EQ(cuts.front(), 0);
        EXPECT_EQ(cuts.back(), nz);
        for (size_t p = 0; p + 1 < cuts.size(); ++p) EXPECT_LT(cuts[p], cuts[p + 1]);
        const double best = best_by_enumeration(w, parts, setup);
        EXPECT_LE(w.max_cost(cuts, setup), best * (1 + 1e-9)) << "trial " << trial;
    }
}

TEST(LightSlabs, UniformWorkWithoutSetUpIsCutEvenly) {
    ChainWork w;
    w.steps.assign(12, 5.0);
    w.starts.assign(12, 0.0);
    w.entering.assign(13, 0.0);
    EXPECT_EQ(balanced_cuts(w, 3, 0.0), (std::vector<int>{0, 4, 8, 12}));
    EXPECT_EQ(balanced_cuts(w, 12, 0.0).size(), 13u);  // a layer each
    EXPECT_THROW(balanced_cuts(w, 13, 0.0), Error);
}

TEST(LightSlabs, ChainWorkOfAUniformMediumLitFromAboveThinsTheTopSlab) {
    // A ray from layer k of a uniform medium under a vertical sun reads the nz - k cells above
    // it (one more voxel each time a piece leaves its slab: the ghost). The pilot must count
    // exactly that, per layer, on any rank count, and the cuts then make the slabs nearer the
    // light thinner (the top rank traces every ray's last piece).
    const int P = test::world_size();
    const Int3 n{8, 8, 8 * P + 8};
    const Decomposition d(MPI_COMM_WORLD, n);
    Field<double> rho(d.local(), 1, 1, 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) { rho(i, j, k) = 1.0; });
    RayGrid slab = make_slab_grid(d, rho);
    const std::vector<DirectionalLight> sun{{"sun", {0, 0, -1}, {1.0}}};
    const ChainWork w = sample_chain_work(d, slab, sun, 2);  // every other column in x and y: 16 rays a layer
    const double per_layer = 16.0;
    EXPECT_EQ(w.rays, static_cast<std::int64_t>(per_layer * n[2]));
    EXPECT_TRUE(w.toward_high_z);
    const std::vector<int> field = d.cuts(2);
    for (int k = 0; k < n[2]; ++k) {
        EXPECT_EQ(w.starts[k], per_layer) << k;
        // Reads in layer k: the rays from layers 0..k; plus the ghost read of every piece that
        // leaves its slab through the top, counted in the slab's top layer.
        double want = per_layer * (k + 1);
        for (size_t p = 1; p < field.size(); ++p)
            if (k == field[p] - 1) want += per_layer * (k + 1);
        EXPECT_EQ(w.steps[k], want) << k;
    }
    for (int f = 0; f <= n[2]; ++f) EXPECT_EQ(w.entering[f], f == n[2] ? 0.0 : per_layer * f) << f;
    const std::vector<int> cuts = balanced_cuts(w, P);
    if (P > 1) {
        EXPECT_GT(cuts[static_cast<size_t>(P) - 1], field[static_cast<size_t>(P) - 1]);  // the top slab is thinner
        EXPECT_LT(w.max_cost(cuts) / w.mean_cost(cuts), w.max_cost(field) / w.mean_cost(field));
    }
    // Lit from below: the same with the slab nearest the light at the bottom.
    const std::vector<DirectionalLight> up{{"up", {0, 0, 1}, {1.0}}};
    const ChainWork m = sample_chain_work(d, slab, up, 2);
    EXPECT_FALSE(m.toward_high_z);
    for (int f = 0; f <= n[2]; ++f) EXPECT_EQ(m.entering[f], f == 0 ? 0.0 : per_layer * (n[2] - f)) << f;
    const std::vector<int> cuts_up = balanced_cuts(m, P);
    if (P > 1) {
        EXPECT_LT(cuts_up[1], field[1]);
        EXPECT_LT(m.max_cost(cuts_up) / m.mean_cost(cuts_up), m.max_cost(field) / m.mean_cost(field));
    }
    EXPECT_THROW(sample_chain_work(d, slab, {sun[0], up[0]}, 2), Error);
}

TEST(LightSlabs, RaysCrossEveryFaceAboveUnlessTheyLeaveSideways) {
    // An oblique sun: over periodic x/y every ray reaches the top, so face f is crossed by the
    // rays of all layers below it; over closed x/y the rays that leave through a side are not,
    // and a face is crossed by at most the rays that crossed the one below or started between.
    const int P = test::world_size();
    const Int3 n{16, 16, 6 * P + 6};
    const std::vector<DirectionalLight> sun{{"sun", normalized(Vec3{0.5, -0.3, -1.0}), {1.0}}};
    for (const bool periodic : {true, false}) {
        const Decomposition d(MPI_COMM_WORLD, n, {0, 0, 0}, {periodic, periodic, false});
        Field<double> rho(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { rho(i, j, k) = (i + j + k) % 3 == 0 ? 1.0 : 0.0; });
        RayGrid slab = make_slab_grid(d, rho);
        const ChainWork w = sample_chain_work(d, slab, sun, 4);  // 16 rays a layer
        for (int f = 1; f < n[2]; ++f) {
            if (periodic) {
                EXPECT_EQ(w.entering[f], 16.0 * f) << f;
            } else {
                EXPECT_LE(w.entering[f], w.entering[f - 1] + w.starts[f - 1]) << f;
                EXPECT_LE(w.entering[f], 16.0 * f) << f;
            }
        }
        // The rays move 0.5 cells in -x per layer: those from x = 0.5 leave after one layer, so
        // the top face sees fewer than all the rays below it.
        if (!periodic) {
            EXPECT_LT(w.entering[n[2] - 1], 16.0 * (n[2] - 1));
        }
        EXPECT_GT(std::accumulate(w.steps.begin(), w.steps.end(), 0.0), 0.0);
    }
}

}  // namespace
}  // namespace nimbus
