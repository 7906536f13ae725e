// Bands that share the LPM map sweeps (src/physics/band_groups.h): three bands with equal optics
// lit by a sun, a light of another colour ("sky[0]") and a volume source of the sun's colour are
// two solves, (sun + source) and sky, and each band equals the band solved alone (the maps and
// the diffusion tail are linear in the source); with the geometric tail, which is not, every
// band is its own solve.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "solvers/lpm/lpm.h"
#include "tests/support/band_copies.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/lpm/lpm_world.h"

namespace nimbus {
namespace {

const std::array<double, 3> kSun = {1.0, 0.95, 0.85};
const std::array<double, 3> kSky = {0.03, 0.05, 0.09};

double puff(int i, int j, int k) {
    const double x = (i + 0.5) / 12.0 - 0.5, y = (j + 0.5) / 12.0 - 0.5, z = (k + 0.5) / 12.0 - 0.45;
    const double r2 = (x * x + y * y + z * z) / 0.16;
    return r2 < 1.0 ? 1.5 * (1.0 - r2) : 0.0;
}

struct BandsRun {
    DiffuseSolution sol;
    nlohmann::json solves;
};

BandsRun solve_bands(const std::vector<int>& bands, const std::string& tail) {
    std::vector<DirectionalLight> lights = {{"sun", normalized(Vec3{0.4, 0.2, -1.0}), {}},
                                            {"sky[0]", normalized(Vec3{-0.3, 0.5, -1.0}), {}}};
    std::vector<double> power;
    for (int b : bands) {
        lights[0].E0.push_back(kSun[static_cast<size_t>(b)]);
        lights[1].E0.push_back(kSky[static_cast<size_t>(b)]);
        power.push_back(0.05 * kSun[static_cast<size_t>(b)]);
    }
    const BandOptics optics{"band", 0.8, 0.95, 0.6};
    test::LpmWorld w(MPI_COMM_WORLD, {12, 12, 12}, {false, false, false}, puff, optics, lights);
    w.m.bands = test::band_copies(optics, bands);
    w.scene.bands = w.m.bands;
    w.scene.grid.cell_size = w.m.grid.h;
    w.scene.sources = {SourceSpec{{3.0, 3.0, 3.0}, {7.0, 6.0, 5.0}, power}};
    LpmOptions o;
    o.p = 3;
    o.k = 1;
    o.tail = tail;
    BandsRun r;
    make_lpm_model(o)->solve(w.ctx(), r.sol);
    r.solves = w.report.values()["lpm"]["solves"];
    return r;
}

// Largest |a - b| of band a_band of `all` and band 0 of `one` over the owned cells, and the
// peak of the latter (all ranks).
std::array<double, 2> band_difference(const Decomposition& d, const DiffuseSolution& all, int a_band,
                                      const DiffuseSolution& one) {
    std::array<double, 2> r{0.0, 0.0};
    for_each_cell(d.local(), [&](int i, int j, int k) {
        r[0] = std::max(r[0], std::abs(all.fluence[static_cast<size_t>(a_band)](i, j, k) - one.fluence[0](i, j, k)));
        r[1] = std::max(r[1], one.fluence[0](i, j, k));
    });
    MPI_Allreduce(MPI_IN_PLACE, r.data(), 2, MPI_DOUBLE, MPI_MAX, d.comm());
    return r;
}

TEST(LpmBands, BandsShareSolvesByLightColour) {
    const BandsRun all = solve_bands({0, 1, 2}, "diffusion");
    ASSERT_EQ(all.solves.size(), 2u) << all.solves.dump();
    for (const auto& s : all.solves) EXPECT_EQ(s["bands"], nlohmann::json::array({"band0", "band1", "band2"}));
    EXPECT_EQ(all.solves[0]["terms"], nlohmann::json::array({"sun", "sources[0]"}));
    EXPECT_EQ(all.solves[1]["terms"], nlohmann::json::array({"sky"}));
    const Decomposition d(MPI_COMM_WORLD, {12, 12, 12});
    for (int b = 0; b < 3; ++b) {
        const BandsRun one = solve_bands({b}, "diffusion");
        ASSERT_EQ(one.solves.size(), 1u);
        const auto [diff, peak] = band_difference(d, all.sol, b, one.sol);
        if (test::world_rank() == 0)
            std::printf("lpm: band %d of 3 bands in 2 solves vs alone: max |diff| / peak = %.2e\n", b, diff / peak);
        EXPECT_GT(peak, 0.0);
        // Measured 1e-13 to 4e-13; the bound is the tail solves' own tolerance (relative residual
        // 1e-8 in each solve, which the sums of two solves and the one solve need not share).
        EXPECT_LE(diff, 1e-7 * peak) << "band " << b;
    }
}

TEST(LpmBands, GeometricTailSolvesEachBand) {
    const BandsRun all = solve_bands({0, 1, 2}, "geometric");
    ASSERT_EQ(all.solves.size(), 3u) << all.solves.dump();
    for (int b = 0; b < 3; ++b) EXPECT_EQ(all.solves[static_cast<size_t>(b)]["bands"], nlohmann::json::array({"band" + std::to_string(b)}));
}

}  // namespace
}  // namespace nimbus
