// Volume emission ([[sources]]) in discrete ordinates (solvers/dom, p.emission = power / 4π):
//   (a) energy balance: emitted = absorbed + leaked to the iteration tolerance, and the
//       emitted power equals power x the volume of the covered cells with density;
//   (b) infinite medium: a uniform source in a cube 80 mean free paths across: the centre
//       fluence is P / (kappa (1 - a)) (the step scheme keeps the infinite-medium solution);
//   (e) the void duct (scenes/duct.toml): DOM at several quadratures against the stored Monte
//       Carlo reference (tests/data/duct_mc_reference.csv, made by jobs/duct/make_reference.sh)
//       on the medium at the duct's end and around it; the ray effect is the DOM error there.
#include "src/scene/emission.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "solvers/dom/dom.h"
#include "tests/support/duct_reference.h"
#include "tests/support/mpi_test.h"
#include "tests/verification/dom/dom_world.h"

namespace nimbus {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(DomEmission, EnergyBalanceAndEmittedPower) {
    const double h = 0.5;
    test::DomWorld w(MPI_COMM_WORLD, {8, 6, 10}, h, BandOptics{"gray", 0.8, 0.9, 0.6});
    // Some empty cells inside the source box: they do not emit.
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        w.m.rho(i, j, k) = (i + j + k) % 5 == 0 ? 0.0 : 0.5 + 0.1 * (k % 3);
    });
    w.scene.grid.cell_size = h;
    w.scene.sources = {SourceSpec{{0.5, 0.5, 0.5}, {2.5, 2.0, 3.0}, {3.0}},
                       SourceSpec{{3.0, 0.0, 3.0}, {4.0, 3.0, 5.0}, {0.5}}};
    DomOptions o;
    o.order = 4;
    o.iteration = "source";
    o.tolerance = 1e-11;
    DiffuseSolution sol;
    make_dom_model(o)->solve(w.ctx(), sol);
    // Expected power: cells with centres in the boxes and density > 0, times power and h³.
    const std::vector<VolumeSource> src = volume_sources(w.scene);
    EXPECT_EQ(src[0].cells, (Box{{1, 1, 1}, {5, 4, 6}}));
    double expected = 0.0;
    for (int k = 0; k < 10; ++k)
        for (int j = 0; j < 6; ++j)
            for (int i = 0; i < 8; ++i)
                if ((i + j + k) % 5 != 0)
                    expected += (src[0].cells.contains(i, j, k) ? 3.0 : 0.0) +
                                (src[1].cells.contains(i, j, k) ? 0.5 : 0.0);
    expected *= h * h * h;
    const auto& band = w.report.values()["dom"]["solves"][0];
    if (test::world_rank() == 0)
        std::printf(
            "dom emission: source power %.6f (expected %.6f), energy balance %.2e after %d "
            "iterations\n",
            band["source_power"].get<double>(), expected, band["energy_balance"].get<double>(),
            band["iterations"].get<int>());
    EXPECT_NEAR(band["source_power"].get<double>(), expected, 1e-12 * expected);
    EXPECT_LT(std::abs(band["energy_balance"].get<double>()), 1e-9);
}

TEST(DomEmission, InfiniteMediumCentreFluence) {
    // 20^3 cells with kappa h = 4 (80 mfp across), a 0.5, g 0.3: the centre 4^3 cells are 32 mfp
    // from the faces, but the step scheme damps the boundary's influence only by mu/(kappa h + mu)
    // >= 1/5 per cell along the most grazing ordinate (0.2^8 ~ 3e-6 here; at 16^3, 0.2^6, the
    // centre was off by 2.4e-5).
    const double h = 0.25, kappa = 16.0, a = 0.5, P = 2.0;
    test::DomWorld w(MPI_COMM_WORLD, {20, 20, 20}, h, BandOptics{"gray", kappa, a, 0.3});
    w.scene.grid.cell_size = h;
    w.scene.sources = {SourceSpec{{0, 0, 0}, {5, 5, 5}, {P}}};
    DomOptions o;
    o.order = 8;
    o.tolerance = 1e-10;
    DiffuseSolution sol;
    make_dom_model(o)->solve(w.ctx(), sol);
    const double exact = P / (kappa * (1.0 - a));
    double worst = 0.0;
    for_each_cell(Box{{8, 8, 8}, {12, 12, 12}}.intersect(w.d.local()), [&](int i, int j, int k) {
        worst = std::max(worst, std::abs(sol.fluence[0](i, j, k) / exact - 1.0));
    });
    MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    if (test::world_rank() == 0)
        std::printf("dom infinite medium: centre max rel. error %.2e\n", worst);
    EXPECT_LT(worst, 1e-5);
}

// ---- (e) the void duct ----------------------------------------------------------------------

struct DuctError {
    double rel_l2 = 0, max_rel = 0, rms_z = 0, max_z = 0, bias = 0;  // bias: Σ(dom - mc) / Σ mc
};

DuctError duct_error(const test::DuctWorld& w, const DiffuseSolution& sol,
                     const test::DuctRegion& ref) {
    double v[5] = {0, 0, 0, 0, 0}, mx[2] = {0, 0};  // Σ e², Σ mc², Σ z², Σ e, count; max rel, max z
    for (const auto& [c, r] : ref) {
        if (!w.d.local().contains(c[0], c[1], c[2])) continue;
        const double e = sol.fluence[0](c[0], c[1], c[2]) - r.mean;
        v[0] += e * e, v[1] += r.mean * r.mean, v[2] += (e / r.se) * (e / r.se), v[3] += e,
            v[4] += 1;
        mx[0] = std::max(mx[0], std::abs(e) / r.mean);
        mx[1] = std::max(mx[1], std::abs(e) / r.se);
    }
    MPI_Allreduce(MPI_IN_PLACE, v, 5, MPI_DOUBLE, MPI_SUM, w.d.comm());
    MPI_Allreduce(MPI_IN_PLACE, mx, 2, MPI_DOUBLE, MPI_MAX, w.d.comm());
    double sum_mc = 0;
    for (const auto& [c, r] : ref) sum_mc += r.mean;
    return {std::sqrt(v[0] / v[1]), mx[0], std::sqrt(v[2] / v[4]), mx[1], v[3] / sum_mc};
}

TEST(DomEmission, VoidDuctRayEffectAgainstMonteCarlo) {
    const auto ref = test::read_duct_reference();
    ASSERT_EQ(ref.count("end"), 1u) << "missing tests/data/duct_mc_reference.csv";
    ASSERT_EQ(ref.count("wall"), 1u);
    ASSERT_EQ(ref.count("source"), 1u);
    test::DuctWorld w(MPI_COMM_WORLD);
    struct Case {
        std::string label, quadrature;
        int order, polar, azimuthal;
    };
    const std::vector<Case> cases = {
        {"S4", "level-symmetric", 4, 0, 0},   {"S8", "level-symmetric", 8, 0, 0},
        {"S12", "level-symmetric", 12, 0, 0}, {"S16", "level-symmetric", 16, 0, 0},
        {"cube96", "cube96", 4, 0, 0},        {"P16x32", "product", 4, 16, 32}};
    std::map<std::string, std::array<DuctError, 3>> err;
    if (test::world_rank() == 0)
        std::printf(
            "void duct (scenes/duct.toml) against MC: region: rel L2, max rel, rms z, max z, "
            "bias\n");
    for (const Case& c : cases) {
        DomOptions o = w.scene.model.dom;
        o.tolerance =
            1e-5;  // the scene's 1e-6 changes no printed digit and costs 2-3 more iterations
        o.quadrature = c.quadrature;
        o.order = c.order;
        if (c.polar) o.polar = c.polar, o.azimuthal = c.azimuthal;
        DiffuseSolution sol;
        make_dom_model(o)->solve(w.ctx(), sol);
        const int ndir = w.report.values()["dom"]["directions"].get<int>();
        const auto& band = w.report.values()["dom"]["solves"][0];
        if (test::world_rank() == 0)
            std::printf("  %-7s %3d dirs  %d iterations, %.2f s\n", c.label.c_str(), ndir,
                        band["iterations"].get<int>(), band["seconds"].get<double>());
        int r = 0;
        for (const char* region : {"end", "wall", "source"}) {
            const DuctError e = duct_error(w, sol, ref.at(region));
            err[c.label][static_cast<size_t>(r++)] = e;
            if (test::world_rank() == 0)
                std::printf(
                    "  %-7s %3d dirs  %-6s rel L2 %.3f  max rel %.3f  rms z %7.1f  max z %7.1f  "
                    "bias %+.3f\n",
                    c.label.c_str(), ndir, region, e.rel_l2, e.max_rel, e.rms_z, e.max_z, e.bias);
        }
    }
    // Bounds from the measured table (solvers/dom/README.md: end 0.764, 0.392, 0.214, 0.134 for
    // S4..S16, 0.073 for the 16 x 32 product set; source 0.087-0.107) with margin. End of the duct
    // (light streaming along it): the error is the ray effect; it falls with every refinement of
    // the level-symmetric sets, S12 at least 2.5x below S4 (measured 3.6x), and the large
    // product set (directions near the duct's axis) is within 12 % of MC (measured 7.3 %).
    const auto end = [&](const char* q) { return err[q][0].rel_l2; };
    EXPECT_GT(end("S4"), end("S8"));
    EXPECT_GT(end("S8"), end("S12"));
    EXPECT_GT(end("S12"), end("S16"));
    EXPECT_LT(end("S12"), end("S4") / 2.5);
    EXPECT_LT(end("S16"), 0.2);
    EXPECT_LT(end("P16x32"), 0.12);
    // Around the end (the medium's cells beside it): S4's few directions miss much of it
    // (measured 0.276); from S8 on the error is the step scheme's, ~0.11 (0.113, 0.107, 0.110,
    // product set 0.114).
    const auto wall = [&](const char* q) { return err[q][1].rel_l2; };
    EXPECT_GT(wall("S4"), 2 * wall("S8"));
    for (const char* q : {"S8", "S12", "S16", "P16x32"}) EXPECT_LT(wall(q), 0.14) << q;
    // Inside the source the light is local and diffuse: the error there is the step scheme's
    // spatial error at optical thickness 1 per cell (~9 %, numerical diffusion lets light leak
    // out of the box), the same for every quadrature: no ray effect.
    double lo = 1, hi = 0;
    for (const auto& [label, e] : err)
        lo = std::min(lo, e[2].rel_l2), hi = std::max(hi, e[2].rel_l2);
    EXPECT_LT(hi, 0.13);
    EXPECT_LT(hi - lo, 0.035);
}

}  // namespace
}  // namespace nimbus
