// A collimated beam in a non-scattering medium keeps its profile exactly through a map
// (Fattal 2009 Fig. 4, right): a square source emits along one map direction only (p = k = 3,
// so the direction has its own coarse bin), tangent 2/3 across the z slabs with R = 3 rays per
// cell, i.e. exactly 2 ray slots per step. Then the cell fluence pattern three layers on is the
// pattern shifted by exactly two cells (to round-off), crossing the rank boundary; a first-order
// upwind transport of the same beam on the same grid spreads it (false scattering).
#include <gtest/gtest.h>

#include <cmath>

#include "solvers/lpm/map_sweep.h"
#include "tests/support/mpi_test.h"

namespace nimbus::lpm {
namespace {

constexpr int NX = 12, NY = 4, NZ = 16;

// Second central moment (width²) and total of a profile along z.
void moments(const std::vector<double>& f, double& total, double& width) {
    double s0 = 0.0, s1 = 0.0, s2 = 0.0;
    for (size_t k = 0; k < f.size(); ++k) {
        s0 += f[k];
        s1 += f[k] * static_cast<double>(k);
        s2 += f[k] * static_cast<double>(k * k);
    }
    total = s0;
    width = std::sqrt(std::max(0.0, s2 / s0 - (s1 / s0) * (s1 / s0)));
}

TEST(LpmBeam, KeepsItsProfileExactlyAcrossRanks) {
    const Decomposition d(MPI_COMM_WORLD, {NX, NY, NZ});
    const Angular ang(3, 3);
    const int face = 0, dir = 2 * 3 + 1;  // +X map, tangents (t_y, t_z) = (0, 2/3)
    const int bin = ang.coarse_of(face * 9 + dir);
    Field<double> kappa(d.local(), 1, 1, 0.0), U(d.local(), 1, ang.coarse_bins(), 0.0), fluence(d.local(), 1, 1, 0.0);
    auto source = [](int i, int j, int k) { return i == 0 && j >= 1 && j < 3 && k >= 2 && k < 4; };
    const Box all = d.local().grown(1);
    for_each_cell(all, [&](int i, int j, int k) {
        if (source(i, j, k)) kappa(i, j, k) = 1.0;  // absorbing, albedo 0
    });
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (source(i, j, k)) U(i, j, k, bin) = 1.0;
    });
    const std::vector<double> deposit(static_cast<size_t>(ang.map_bins() * ang.coarse_bins()), 0.0);
    MapInputs in;
    in.angular = &ang;
    in.refinement = 3;
    in.kappa = &kappa;
    in.albedo = 0.0;
    in.deposit = &deposit;
    MapAccumulators acc;
    acc.U = &U;
    acc.fluence = &fluence;
    sweep_map(d, face, in, acc);

    // Global fluence [x][z] at y = 1 (the beam is uniform over y in [1, 3)).
    std::vector<double> g(static_cast<size_t>(NX * NZ), 0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (j == 1) g[static_cast<size_t>(i * NZ + k)] = fluence(i, j, k);
    });
    MPI_Allreduce(MPI_IN_PLACE, g.data(), static_cast<int>(g.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    auto at = [&](int i, int k) { return g[static_cast<size_t>(i * NZ + k)]; };
    double peak = 0.0;
    for (double v : g) peak = std::max(peak, v);
    ASSERT_GT(peak, 0.0);
    double worst = 0.0;
    for (int i = 1; i + 3 < NX; ++i)
        for (int k = 0; k + 2 < NZ; ++k) worst = std::max(worst, std::abs(at(i + 3, k + 2) - at(i, k)));
    EXPECT_LE(worst, 1e-14 * peak) << "profile not carried exactly";

    // The same beam by first-order upwind (step scheme) from the LPM's profile at x = 1.
    const Vec3 w = ang.direction(face * 9 + dir);
    std::vector<double> up(static_cast<size_t>(NX * NZ), 0.0);
    for (int k = 0; k < NZ; ++k) up[static_cast<size_t>(1 * NZ + k)] = at(1, k);
    for (int i = 2; i < NX; ++i)
        for (int k = 0; k < NZ; ++k) {
            const double below = k > 0 ? up[static_cast<size_t>(i * NZ + k - 1)] : 0.0;
            up[static_cast<size_t>(i * NZ + k)] = (w.x * up[static_cast<size_t>((i - 1) * NZ + k)] + w.z * below) / (w.x + w.z);
        }
    auto column = [&](const std::vector<double>& f, int i) {
        return std::vector<double>(f.begin() + i * NZ, f.begin() + (i + 1) * NZ);
    };
    double t1, w1, t10, w10, tu10, wu10;
    moments(column(g, 1), t1, w1);
    moments(column(g, 10), t10, w10);
    moments(column(up, 10), tu10, wu10);
    EXPECT_NEAR(t10, t1, 1e-13 * t1);    // power carried (vacuum)
    EXPECT_NEAR(w10, w1, 1e-12 * w1);    // width unchanged
    EXPECT_GT(wu10, 1.5 * w1);           // the upwind beam spreads
    double peak1 = 0.0, peak10 = 0.0, peak_up = 0.0;
    for (int k = 0; k < NZ; ++k) {
        peak1 = std::max(peak1, at(1, k));
        peak10 = std::max(peak10, at(10, k));
        peak_up = std::max(peak_up, up[static_cast<size_t>(10 * NZ + k)]);
    }
    if (test::world_rank() == 0)
        std::printf("    beam width (cells, rms along z) at x=1: %.4f; at x=10: LPM %.4f, upwind %.4f; "
                    "peak at x=10: LPM %.4f, upwind %.4f of the x=1 peak\n",
                    w1, w10, wu10, peak10 / peak1, peak_up / peak1);
}

}  // namespace
}  // namespace nimbus::lpm
