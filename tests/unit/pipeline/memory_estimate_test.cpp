// The memory estimate that `info` and `run` check before allocating (src/cmd/memory.h): each
// model's own storage (ScatteringModel::memory_bytes) is in it, and grows with what the model
// stores per cell. The calibration against measured peaks is in the README ("Running").
#include <gtest/gtest.h>

#include <string>

#include "io/scene/scene_toml.h"
#include "src/cmd/memory.h"
#include "src/scene/scene.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

double estimate(const std::string& model, void (*tweak)(Scene&) = nullptr) {
    Scene s = default_scene();
    s.grid.n = {48, 48, 32};
    s.model.name = model;
    if (tweak) tweak(s);
    const Decomposition d(MPI_COMM_WORLD, s.grid.n);
    return cmd::estimate_memory(s, d).bytes;
}

// DOM keeps every direction's periodic ghost planes between sweeps (transport_sweep.h):
// (ny + nx) nz values per direction with x and y periodic, 24 directions at S4.
TEST(MemoryEstimate, DomCountsItsPeriodicPlanes) {
    Scene s = default_scene();
    s.grid.n = {48, 40, 32};
    s.model.name = "dom";
    const Decomposition flat(MPI_COMM_WORLD, s.grid.n);
    const double without = cmd::estimate_memory(s, flat).bytes;
    s.grid.periodic = {true, true, false};
    const Decomposition periodic(MPI_COMM_WORLD, s.grid.n, {0, 0, 0}, s.grid.periodic);
    const double extra = cmd::estimate_memory(s, periodic).bytes - without;  // this rank's
    EXPECT_DOUBLE_EQ(extra, 8.0 * 24 * (40 + 48) * periodic.local().size(2));
}

TEST(MemoryEstimate, EachModelAddsItsStorage) {
    const double single = estimate("single");
    for (const char* m : {"diffusion", "dom", "lpm", "psf", "montecarlo"}) EXPECT_GT(estimate(m), single) << m;
    // DOM: more directions and moments, and GMRES's Krylov basis, cost more.
    const double s4 = estimate("dom");
    EXPECT_GT(estimate("dom", [](Scene& s) { s.model.dom.order = 8, s.model.dom.legendre_order = 7; }), 2 * s4 - single);
    EXPECT_GT(estimate("dom", [](Scene& s) { s.model.dom.iteration = "gmres"; }), 2 * s4 - single);
    // Each octant in flight holds its own psi and source (step scheme: 2 values per direction).
    const Decomposition d(MPI_COMM_WORLD, {48, 48, 32});
    EXPECT_DOUBLE_EQ(s4 - estimate("dom", [](Scene& s) { s.model.dom.octant_overlap = 1; }),
                     8.0 * 7 * 2 * 3 * static_cast<double>(d.local().cells()));  // S4: 3 directions per octant
    // LPM: 6k² coarse bins per cell, and p² rays per cell of its map planes (R² per slot on the
    // lateral maps) with their sweep buffers: 1.3 x 8 p² (nx ny + 2 R² max(nx, ny) nz) bytes of
    // the rank's box (1.3 measured; the sums are not exact in binary: compared to 1e-12).
    EXPECT_GT(estimate("lpm", [](Scene& s) { s.model.lpm.p = 3, s.model.lpm.k = 3; }),
              estimate("lpm", [](Scene& s) { s.model.lpm.p = 3, s.model.lpm.k = 1; }));
    const double planes = 48.0 * 48 + 2.0 * 48 * d.local().size(2);
    const double by_p = 1.3 * 8.0 * (24 * 24 - 6 * 6) * planes;
    EXPECT_NEAR(estimate("lpm", [](Scene& s) { s.model.lpm.p = 24; }) - estimate("lpm", [](Scene& s) { s.model.lpm.p = 6; }),
                by_p, 1e-12 * estimate("lpm"));
    const double by_r = 1.3 * 8.0 * 36 * 2 * (16 - 1) * 48 * d.local().size(2);
    EXPECT_NEAR(estimate("lpm", [](Scene& s) { s.model.lpm.refinement = 4; }) - estimate("lpm"), by_r,
                1e-12 * estimate("lpm"));
    // A periodic x or y also keeps the last K = p / gcd(p, n R) lateral maps (the cyclic sweeps'
    // filling test): 8 p² K R² max(nx, ny) nz; 48 cells and p 6: K = 1; p 18: K = 3.
    const auto periodic = [](Scene& s) { s.grid.periodic = {true, true, false}; };
    const auto lpm_estimate = [&](int p, bool per) {
        Scene s = default_scene();
        s.grid.n = {48, 48, 32};
        s.model.name = "lpm";
        s.model.lpm.p = p;
        if (per) periodic(s);
        const Decomposition dd(MPI_COMM_WORLD, s.grid.n, {0, 0, 0}, s.grid.periodic);
        return cmd::estimate_memory(s, dd).bytes;
    };
    const double lateral = 48.0 * d.local().size(2);
    EXPECT_NEAR(lpm_estimate(6, true) - lpm_estimate(6, false), 8.0 * 36 * 1 * lateral, 1e-12 * lpm_estimate(6, true));
    EXPECT_NEAR(lpm_estimate(18, true) - lpm_estimate(18, false), 8.0 * 324 * 3 * lateral, 1e-12 * lpm_estimate(18, true));
    // Diffusion: SMG's plane solvers and PETSc's copy with its AMG hierarchy.
    const double pfmg = estimate("diffusion");
    EXPECT_DOUBLE_EQ(estimate("diffusion", [](Scene& s) { s.model.diffusion.solver = "smg-pcg"; }) - pfmg,
                     8.0 * 23 * static_cast<double>(d.local().cells()));
    EXPECT_DOUBLE_EQ(estimate("diffusion", [](Scene& s) { s.model.diffusion.solver = "petsc"; }) - pfmg,
                     8.0 * 33 * static_cast<double>(d.local().cells()));
    // Diffusion and LPM hold the first-scatter means they keep, one double per cell and light
    // term, at most FirstScatterMeans::kMaxKeptLights (16): the sky's 8 directions and the sun are
    // 9 terms, 12 directions 13, 40 directions 41 (16 kept). The light pass's own storage per term
    // is in single's estimate as well and cancels.
    const auto model_part = [](const char* m, void (*tweak)(Scene&)) { return estimate(m, tweak) - estimate("single", tweak); };
    const auto sky12 = [](Scene& s) { s.sky.directions = 12; };
    const auto sky40 = [](Scene& s) { s.sky.directions = 40; };
    const double cells = static_cast<double>(d.local().cells());
    for (const char* m : {"diffusion", "lpm"}) {
        EXPECT_DOUBLE_EQ(model_part(m, sky12) - model_part(m, nullptr), 8.0 * 4 * cells) << m;
        EXPECT_DOUBLE_EQ(model_part(m, sky40) - model_part(m, nullptr), 8.0 * 7 * cells) << m;
    }
    // PSF: a rank's share does not shrink as 1/P: level 0 keeps 3 ghost layers each side, and on
    // more than one rank the light depths are gathered over the layers a rank marches (the
    // estimate scaled as cells / P and was 24-27% below the measured peak at 2-4 ranks).
    const auto psf_share = [](MPI_Comm comm) {
        Scene s = default_scene();
        s.grid.n = {48, 48, 32};
        s.camera.width = s.camera.height = 1;  // the render's per-pixel share is the same on every rank
        const Decomposition dd(comm, s.grid.n);
        s.model.name = "single";
        const double base = cmd::estimate_memory(s, dd).bytes;
        s.model.name = "psf";
        return cmd::estimate_memory(s, dd).bytes - base;
    };
    const double one = psf_share(MPI_COMM_SELF), all = psf_share(MPI_COMM_WORLD);
    if (d.size() > 1) {
        EXPECT_GT(all, 1.3 * one / d.size());
    }
    // The figure says what it covers.
    const std::string what = [] {
        Scene s = default_scene();
        return cmd::estimate_memory(s, Decomposition(MPI_COMM_WORLD, s.grid.n)).what;
    }();
    EXPECT_NE(what.find("model montecarlo"), std::string::npos) << what;
}

}  // namespace
}  // namespace nimbus
