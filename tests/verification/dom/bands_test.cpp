// Bands that share a DOM solve (src/physics/band_groups.h): three bands with equal optics lit by
// a sun, a second light of another colour ("sky[0]") and a volume source of the sun's colour are
// two solves, (sun + source) and sky, and each band equals the band solved alone to the
// iteration tolerance; the same with the sky as boundary radiance (sky = "boundary"), where the
// sky is a source term of its own. The report names the bands and terms of each solve, and each
// solve's energy balance closes (the sky's too, on the power it brings in through the faces).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "solvers/dom/dom.h"
#include "tests/support/band_copies.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/dom/dom_world.h"

namespace nimbus {
namespace {

constexpr int kN = 8;
constexpr double kH = 0.25;
constexpr double kTolerance = 1e-10;
const std::array<double, 3> kSun = {1.0, 0.95, 0.85};
const std::array<double, 3> kSky = {0.03, 0.05, 0.09};  // second light's E0, or the sky's radiance

struct BandsRun {
    DiffuseSolution sol;
    nlohmann::json solves;
};

// The cube with the given bands of equal optics; sky: "first-collision" (a second light from
// another direction) or "boundary" (uniform sky radiance on the open faces).
BandsRun solve_bands(const std::vector<int>& bands, const std::string& sky) {
    const BandOptics optics{"band", 1.0, 0.95, 0.6};
    test::DomWorld w(MPI_COMM_WORLD, {kN, kN, kN}, kH, optics);
    // Uneven density with a few empty cells.
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        w.m.rho(i, j, k) = (i * 3 + j * 5 + k) % 7 == 0 ? 0.0 : 0.4 + 0.15 * ((i + 2 * j + k) % 5);
    });
    exchange_halo(w.m.rho, w.d);
    w.m.bands = test::band_copies(optics, bands);
    w.scene.bands = w.m.bands;
    w.scene.grid.cell_size = kH;
    w.add_sun_from_top({0.3, 0.2, -1.0});
    w.light.lights[0].E0.clear();
    for (int b : bands) w.light.lights[0].E0.push_back(kSun[static_cast<size_t>(b)]);
    if (sky == "first-collision") {
        // Any optical depth field will do for a superposition test: that of a steeper light.
        w.add_sun_from_top({-0.2, 0.1, -1.0});
        w.light.lights[1].name = "sky[0]";
        w.light.lights[1].E0.clear();
        for (int b : bands) w.light.lights[1].E0.push_back(kSky[static_cast<size_t>(b)]);
    } else {
        for (int b : bands) w.scene.sky.radiance.push_back(kSky[static_cast<size_t>(b)]);
    }
    std::vector<double> power;
    for (int b : bands) power.push_back(0.5 * kSun[static_cast<size_t>(b)]);
    w.scene.sources = {SourceSpec{{0.5, 0.5, 0.5}, {1.5, 1.25, 1.0}, power}};
    DomOptions o;
    o.order = 4;
    o.legendre_order = 3;
    o.tolerance = kTolerance;
    o.sky = sky;
    BandsRun r;
    make_dom_model(o)->solve(w.ctx(), r.sol);
    r.solves = w.report.values()["dom"]["solves"];
    return r;
}

void expect_bands_equal_alone(const std::string& sky) {
    const BandsRun all = solve_bands({0, 1, 2}, sky);
    ASSERT_EQ(all.solves.size(), 2u) << all.solves.dump();
    for (const auto& s : all.solves) EXPECT_EQ(s["bands"], nlohmann::json::array({"band0", "band1", "band2"}));
    EXPECT_EQ(all.solves[0]["terms"], nlohmann::json::array({"sun", "sources[0]"}));
    EXPECT_EQ(all.solves[1]["terms"], nlohmann::json::array({"sky"}));
    // Every solve closes its energy balance, the sky's alone too: as boundary radiance its power
    // comes in through the faces (sky_incoming_power), not from a volume source.
    for (const auto& s : all.solves) EXPECT_LT(std::abs(s["energy_balance"].get<double>()), 1e-8) << s.dump();
    if (sky == "boundary") {
        EXPECT_EQ(all.solves[1]["source_power"].get<double>(), 0.0);
        EXPECT_GT(all.solves[1]["sky_incoming_power"].get<double>(), 0.0);
    }
    Decomposition d(MPI_COMM_WORLD, {kN, kN, kN});
    for (int b = 0; b < 3; ++b) {
        const BandsRun one = solve_bands({b}, sky);
        ASSERT_EQ(one.solves.size(), 1u);
        DiffuseSolution band;  // band b of the shared solves, as band 0
        band.fluence.push_back(all.sol.fluence[static_cast<size_t>(b)]);
        band.flux.push_back(all.sol.flux[static_cast<size_t>(b)]);
        const test::SolutionDifference diff = test::solution_difference(d, band, one.sol);
        if (test::world_rank() == 0)
            std::printf("dom, sky %s: band %d of 3 bands in 2 solves vs alone: max |diff| / peak = %.2e\n",
                        sky.c_str(), b, diff.diff / diff.peak);
        EXPECT_GT(diff.peak, 0.0);
        EXPECT_LE(diff.diff, 1e3 * kTolerance * diff.peak) << "band " << b;
    }
}

TEST(DomBands, BandsShareSolvesByLightColour) { expect_bands_equal_alone("first-collision"); }

TEST(DomBands, BandsShareSolvesWithTheSkyAsBoundaryRadiance) { expect_bands_equal_alone("boundary"); }

}  // namespace
}  // namespace nimbus
