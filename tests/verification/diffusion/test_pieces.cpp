// The pieces of a cloud (cloud_pieces.h) and the transport cap taken per piece (solve_region.h):
// - find_cloud_pieces equals a serial flood fill of the whole grid, cell by cell, on 1, 2 and 3
//   ranks split along z or x, with and without periodic axes;
// - a speck of density in a far corner leaves a cloud's fluence as it was (to the solver
//   tolerance); with the cap from the bounding box of all full cells it moved it.
#include <gtest/gtest.h>

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "solvers/diffusion/cloud_pieces.h"
#include "solvers/diffusion/diffusion.h"
#include "src/core/halo.h"
#include "src/scene/medium.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/diffusion/diffusion_test_util.h"

namespace nimbus {
namespace {

// About 45% of the cells below z = zmax full, from an integer hash: many pieces, some of one
// cell, some crossing the rank boundaries and the periodic faces.
int zmax = 1 << 30;
bool full_cell(int i, int j, int k) {
    if (k >= zmax) return false;
    std::uint32_t x = static_cast<std::uint32_t>(i * 73856093) ^ static_cast<std::uint32_t>(j * 19349663) ^
                      static_cast<std::uint32_t>(k * 83492791);
    x ^= x >> 13;
    x *= 0x5bd1e995u;
    x ^= x >> 15;
    return x % 100 < 45;
}

// The pieces of the whole grid by breadth-first search from each not yet visited full cell in
// global order (x fastest), so that piece q is the one whose lowest cell comes q-th, as
// find_cloud_pieces orders them.
struct Serial {
    std::vector<int> piece;  // per cell, -1 empty
    std::vector<Box> bounds;
    std::vector<std::int64_t> cells;
};

Serial flood_fill(const Int3& n, const std::array<bool, 3>& periodic) {
    Serial s;
    const auto at = [&](int i, int j, int k) { return static_cast<size_t>(i + n[0] * (j + n[1] * k)); };
    s.piece.assign(static_cast<size_t>(n[0] * n[1] * n[2]), -1);
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i) {
                if (!full_cell(i, j, k) || s.piece[at(i, j, k)] >= 0) continue;
                const int q = static_cast<int>(s.bounds.size());
                Box b{{i, j, k}, {i + 1, j + 1, k + 1}};
                std::int64_t count = 0;
                std::deque<Int3> todo{{i, j, k}};
                s.piece[at(i, j, k)] = q;
                while (!todo.empty()) {
                    const Int3 c = todo.front();
                    todo.pop_front();
                    ++count;
                    for (int a = 0; a < 3; ++a) {
                        b.lo[a] = std::min(b.lo[a], c[a]);
                        b.hi[a] = std::max(b.hi[a], c[a] + 1);
                    }
                    for (int a = 0; a < 3; ++a)
                        for (int side : {-1, 1}) {
                            Int3 nb = c;
                            nb[a] += side;
                            if (nb[a] < 0 || nb[a] >= n[a]) {
                                if (!periodic[a]) continue;
                                nb[a] = (nb[a] + n[a]) % n[a];
                            }
                            if (!full_cell(nb[0], nb[1], nb[2]) || s.piece[at(nb[0], nb[1], nb[2])] >= 0) continue;
                            s.piece[at(nb[0], nb[1], nb[2])] = q;
                            todo.push_back(nb);
                        }
                }
                for (int a = 0; a < 3; ++a)
                    if (periodic[a]) b = b.with_range(a, 0, n[a]);
                s.bounds.push_back(b);
                s.cells.push_back(count);
            }
    return s;
}

// Also with the cells only in the lowest 3 layers, so that on 2 and 3 ranks split along z the
// upper ranks hold none (their part of the region is empty unless z is periodic).
TEST(CloudPieces, EqualASerialFloodFillOnAnySplit) {
    const Int3 n{13, 11, 10};
    const int size = test::world_size();
    for (const int top : {n[2], 3})
    for (const Int3 dims : {Int3{1, 1, size}, Int3{size, 1, 1}})
        for (const std::array<bool, 3> periodic :
             {std::array<bool, 3>{false, false, false}, std::array<bool, 3>{true, false, false},
              std::array<bool, 3>{true, true, true}}) {
            zmax = top;
            const std::string what = "cells below z = " + std::to_string(top) + ", dims " + std::to_string(dims[0]) +
                                     "x" + std::to_string(dims[2]) + ", periodic " + std::to_string(periodic[0]) +
                                     std::to_string(periodic[1]) + std::to_string(periodic[2]);
            Decomposition d(MPI_COMM_WORLD, n, dims, periodic);
            Field<double> kappa_tr(d.local(), 1, 1, 0.0);
            for_each_cell(d.local(), [&](int i, int j, int k) { kappa_tr(i, j, k) = full_cell(i, j, k) ? 0.5 : 0.0; });
            // The region holds the full cells and is whole along periodic axes (as SolveRegion's).
            const Box region = periodic[2] ? d.global() : d.global().with_range(2, 0, top);
            const diffusion::CloudPieces pieces = diffusion::find_cloud_pieces(d, kappa_tr, region);
            const Serial want = flood_fill(n, periodic);
            ASSERT_EQ(pieces.bounds.size(), want.bounds.size()) << what;
            EXPECT_GT(want.bounds.size(), top == n[2] ? 20u : 8u) << what;  // a real test: many pieces
            for (size_t q = 0; q < want.bounds.size(); ++q) {
                EXPECT_EQ(pieces.bounds[q], want.bounds[q]) << what << ", piece " << q;
                EXPECT_EQ(pieces.cells[q], want.cells[q]) << what << ", piece " << q;
            }
            int wrong = 0;
            EXPECT_EQ(pieces.index.owned(), d.local().intersect(region)) << what;
            for_each_cell(pieces.index.owned(), [&](int i, int j, int k) {
                wrong += pieces.index(i, j, k) != want.piece[static_cast<size_t>(i + n[0] * (j + n[1] * k))];
            });
            EXPECT_EQ(test::global_sum(wrong, MPI_COMM_WORLD), 0) << what;
        }
}

// A speck of density 1e-6 in a far corner, outside the cloud's shadow, is a piece of its own:
// the cloud's fluence is the same with it and without it, to the solver tolerance. With the cap
// from the bounding box of every full cell (before the forty-fifth session) it moved by
// 3.5e-2 of the largest fluence on this cloud (3.9% on a scene of the forty-third session's QA).
TEST(DiffusionPieces, ASpeckElsewhereDoesNotChangeACloud) {
    constexpr int kN = 24;
    constexpr double kH = 0.25, kTol = 1e-10;
    const BandOptics band{"gray", 3.0, 0.9, 0.85};
    const Vec3 sun = normalized(Vec3{0.3, 0.2, -1.0});  // towards +x, +y, -z: the corner below is downstream
    static const ProceduralDensity density(MediumSpec{}, {kN, kN, kN});
    const auto cloud = [&](int i, int j, int k) { return density(i, j, k); };
    const auto with_speck = [&](int i, int j, int k) {
        return (i == kN - 1 && j == kN - 1 && k == 0) ? 1e-6 : density(i, j, k);
    };
    ASSERT_EQ(density(kN - 1, kN - 1, 0), 0.0);
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    DiffusionOptions opt;
    opt.tolerance = kTol;
    Report r0, r1;
    auto model = make_diffusion_model(opt);
    const DiffuseSolution alone = test::run_model(*model, d, kH, band, cloud, sun, r0);
    const DiffuseSolution speck = test::run_model(*model, d, kH, band, with_speck, sun, r1);
    EXPECT_EQ(r1.values()["diffusion"]["pieces"].get<int>(), r0.values()["diffusion"]["pieces"].get<int>() + 1);
    EXPECT_EQ(r1.values()["diffusion"]["kappa_tr_floor"], r0.values()["diffusion"]["kappa_tr_floor"]);
    // The cloud's cells: all but the speck's.
    Field<double> a = alone.fluence[0], b = speck.fluence[0];
    if (d.local().contains(kN - 1, kN - 1, 0)) a(kN - 1, kN - 1, 0) = b(kN - 1, kN - 1, 0) = 0.0;
    const auto [diff, umax] = test::max_diff(a, b, d.local(), MPI_COMM_WORLD);
    if (test::world_rank() == 0) std::printf("speck: max |diff| / max = %.2e\n", diff / umax);
    EXPECT_GT(umax, 0.0);
    EXPECT_LE(diff, 100 * kTol * umax);
}

}  // namespace
}  // namespace nimbus
