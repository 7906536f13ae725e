// The Monte Carlo model through the ScatteringModel interface: solve() fills fluence and its
// standard error and reports its figures of merit; render() path-traces the camera image
// (pure absorber: each sample sees the background with probability T, so the pixel mean is
// background x (1 - alpha), also through one tile of a periodic domain; with a volume source
// over a uniform absorber it adds q (1 - T) / kappa, and with scattering the source's image
// adds to the sun's sample by sample); the image does not depend on the rank count.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "solvers/montecarlo/montecarlo.h"
#include "src/core/error.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

struct World {
    Scene scene;
    Decomposition d;
    Medium m;
    LightTransport light;
    Report report;
    // uniform: density 0.6 everywhere (else 0.5-0.7 by cell); h: cell edge, m
    World(MPI_Comm comm, double albedo, bool uniform = false, double h = 1.0,
          std::array<bool, 3> periodic = {false, false, false})
        : d(comm, {8, 8, 8}, {0, 0, 0}, periodic) {
        scene.grid.n = {8, 8, 8};
        scene.grid.cell_size = h;
        scene.camera.position = {0.5, 0.5, 3.0};
        scene.camera.look_at = {0.5, 0.5, 0.0};
        scene.camera.up = {0, 1, 0};
        scene.camera.fov_deg = 1.0;
        scene.camera.width = 6;
        scene.camera.height = 4;
        scene.background.color = {0.5};
        m.grid.n = {8, 8, 8};
        m.grid.h = h;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            m.rho(i, j, k) = uniform ? 0.6 : 0.5 + 0.1 * ((i + 2 * j + k) % 3);
        });
        m.bands = {BandOptics{"gray", 0.3, albedo, 0.6}};
        light.lights = {DirectionalLight{"sun", normalized(Vec3{0.2, 0.1, -1.0}), {1.0}}};
    }
    SolveContext ctx() { return {scene, d, m, light, report}; }
};

TEST(MonteCarloModel, SolveFillsFluenceStderrAndReport) {
    World w(MPI_COMM_WORLD, 0.9);
    MonteCarloOptions o;
    o.photons = 4000;
    auto model = make_montecarlo_model(o);
    DiffuseSolution sol;
    model->solve(w.ctx(), sol);
    ASSERT_EQ(sol.fluence.size(), 1u);
    ASSERT_EQ(sol.fluence_stderr.size(), 1u);
    double total = 0.0;
    for_each_cell(w.d.local(), [&](int i, int j, int k) { total += sol.fluence[0](i, j, k); });
    MPI_Allreduce(MPI_IN_PLACE, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_GT(total, 0.0);
    const auto& r = w.report.values()["montecarlo"];
    EXPECT_EQ(r["photons"].get<std::int64_t>(), 4000);
    EXPECT_GT(r["collisions_per_s_per_core"].get<double>(), 0.0);
    EXPECT_EQ(model->options()["photons"].get<std::int64_t>(), 4000);
    EXPECT_FALSE(model->renders_image());
}

// model.montecarlo.flux (off by default): the flux tally adds flux_diffuse (3 components per band) and changes
// neither the paths nor the fluence; without it the model gives no flux (the ray caster then
// takes the in-scatter as isotropic).
TEST(MonteCarloModel, FluxOptionAddsTheFluxAndKeepsTheFluence) {
    World w(MPI_COMM_WORLD, 0.9);
    MonteCarloOptions o;
    o.photons = 4000;
    o.flux = true;
    DiffuseSolution with, without;
    make_montecarlo_model(o)->solve(w.ctx(), with);
    o.flux = false;
    make_montecarlo_model(o)->solve(w.ctx(), without);
    ASSERT_EQ(with.flux.size(), 1u);
    EXPECT_EQ(with.flux[0].ncomp(), 3);
    EXPECT_TRUE(without.flux.empty());
    double flux_norm = 0.0;
    for_each_cell(w.d.local(), [&](int i, int j, int k) {
        EXPECT_EQ(with.fluence[0](i, j, k), without.fluence[0](i, j, k));
        EXPECT_EQ(with.fluence_stderr[0](i, j, k), without.fluence_stderr[0](i, j, k));
        for (int a = 0; a < 3; ++a) flux_norm += std::abs(with.flux[0](i, j, k, a));
    });
    MPI_Allreduce(MPI_IN_PLACE, &flux_norm, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_GT(flux_norm, 0.0);
}

// Path-traces w's camera image with 4000 samples per pixel; on rank 0 checks every pixel of
// the 6 x 4 image against expect(alpha) within 4 standard errors (rms z < 1.6), and returns
// the image (empty on other ranks).
template <class Expect>
Image check_image_z(World& w, Expect&& expect) {
    MonteCarloOptions o;
    o.image = true;
    o.samples_per_pixel = 4000;
    auto model = make_montecarlo_model(o);
    EXPECT_TRUE(model->renders_image());
    Image img = model->render(w.ctx());
    if (test::world_rank() != 0) {
        EXPECT_TRUE(img.empty());
        return img;
    }
    EXPECT_EQ(img.width, 6);
    EXPECT_EQ(img.height, 4);
    double z2 = 0.0;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x) {
            const float* p = img.pixel(x, y);
            const double want = expect(p[3]);
            const double se = img.stderr_rgb[static_cast<size_t>(y * 6 + x) * 3];
            const double z = (p[0] - want) / se;
            z2 += z * z;
            EXPECT_LT(std::abs(z), 4.0) << p[0] << " vs " << want << " (se " << se << ")";
            EXPECT_EQ(p[0], p[1]);
        }
    EXPECT_LT(std::sqrt(z2 / 24.0), 1.6);
    return img;
}

TEST(MonteCarloModel, AbsorberImageIsBackgroundTimesTransmittance) {
    World w(MPI_COMM_WORLD, 0.0);
    const Image img = check_image_z(w, [](double alpha) { return 0.5 * (1.0 - alpha); });
    if (test::world_rank() != 0) return;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x) {
            EXPECT_GT(img.pixel(x, y)[3], 0.7);  // tau = 0.3 * (0.5..0.7) * 8 ≈ 1.44 straight down: T ≈ 0.24
            EXPECT_LT(img.pixel(x, y)[3], 0.8);
        }
}

// The camera sees one tile of a periodic domain, as the ray caster does: a view ray along x
// through a uniform absorber periodic in x and y leaves after the tile's 8 cells (alpha =
// 1 - e^{-8 kappa h}) instead of wrapping for ever (alpha 1, a black pixel).
TEST(MonteCarloModel, CameraRaysSeeOneTileOfAPeriodicDomain) {
    World w(MPI_COMM_WORLD, 0.0, true, 1.0, {true, true, false});
    w.scene.camera.position = {-3.0, 0.5, 0.5};
    w.scene.camera.look_at = {0.5, 0.5, 0.5};
    w.scene.camera.up = {0, 0, 1};
    const double kappa = 0.6 * 0.3;
    const Image img = check_image_z(w, [](double alpha) { return 0.5 * (1.0 - alpha); });
    if (test::world_rank() != 0) return;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x) EXPECT_NEAR(1.0 - img.pixel(x, y)[3], std::exp(-kappa * 8), 1e-3);
}

// Pure absorber of uniform kappa with a source over the whole domain: along a chord of length
// L, I = I0 T + q (1 - T) / kappa, T = e^{-kappa L} = 1 - alpha (Max 1995 eq. 8 with C = q/kappa).
TEST(MonteCarloModel, VolumeSourceGlowsInTheImage) {
    const double h = 0.5;  // m: the emission's length scale is tested too
    World w(MPI_COMM_WORLD, 0.0, true, h);
    const double power = 2.0, kappa = 0.6 * 0.3, q = power / (4 * std::numbers::pi);
    w.scene.sources = {SourceSpec{{0, 0, 0}, {8 * h, 8 * h, 8 * h}, {power}}};
    const Image img = check_image_z(w, [&](double alpha) { return 0.5 * (1.0 - alpha) + q * alpha / kappa; });
    if (test::world_rank() != 0) return;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x)  // straight down through 8 cells
            EXPECT_NEAR(1.0 - img.pixel(x, y)[3], std::exp(-kappa * 8 * h), 1e-4);
}

// The emission tally draws no random numbers, so with the same seed each sample's path is the
// same with and without the source: image(sun + source) = image(sun) + image(source alone) up
// to round-off, including the emission seen along scattered paths.
TEST(MonteCarloModel, VolumeSourceAddsToTheSunlitImage) {
    World sun(MPI_COMM_WORLD, 0.9), both(MPI_COMM_WORLD, 0.9), glow(MPI_COMM_WORLD, 0.9);
    const SourceSpec box{{2, 1, 3}, {6, 7, 8}, {1.5}};
    both.scene.sources = {box};
    glow.scene.sources = {box};
    glow.light.lights[0].E0 = {0.0};
    sun.scene.background.color = both.scene.background.color = glow.scene.background.color = {0.0};
    MonteCarloOptions o;
    o.image = true;
    o.samples_per_pixel = 64;
    const Image a = make_montecarlo_model(o)->render(sun.ctx());
    const Image b = make_montecarlo_model(o)->render(both.ctx());
    const Image c = make_montecarlo_model(o)->render(glow.ctx());
    if (test::world_rank() != 0) return;
    double glow_sum = 0.0;
    for (size_t i = 0; i < a.rgba.size(); ++i) {
        if (i % 4 == 3) continue;  // alpha
        EXPECT_NEAR(b.rgba[i], a.rgba[i] + c.rgba[i], 1e-5 * (a.rgba[i] + c.rgba[i]) + 1e-12);
        glow_sum += c.rgba[i];
    }
    EXPECT_GT(glow_sum, 0.0);
}

// Bands with equal optics share their camera paths (one walk per group): the 3-band image
// equals, channel by channel, 1-band images with each band's sun, background and emission (the
// same seed gives the same paths), and the channels' noise is correlated, not coloured.
TEST(MonteCarloModel, BandsWithEqualOpticsShareTheirPaths) {
    const std::vector<double> E0 = {1.0, 0.5, 0.25}, bg = {0.2, 0.4, 0.6}, power = {1.5, 0.7, 0.3};
    auto setup = [](World& w, std::vector<double> e, std::vector<double> b, std::vector<double> p) {
        const BandOptics o = w.m.bands[0];
        w.m.bands.assign(e.size(), o);
        w.scene.bands = w.m.bands;
        w.light.lights[0].E0 = std::move(e);
        w.scene.background.color = std::move(b);
        w.scene.sources = {SourceSpec{{2, 1, 3}, {6, 7, 8}, std::move(p)}};
    };
    MonteCarloOptions o;
    o.image = true;
    o.samples_per_pixel = 32;
    World three(MPI_COMM_WORLD, 0.9);
    setup(three, E0, bg, power);
    const Image all = make_montecarlo_model(o)->render(three.ctx());
    for (int b = 0; b < 3; ++b) {
        World one(MPI_COMM_WORLD, 0.9);
        setup(one, {E0[b]}, {bg[b]}, {power[b]});
        const Image single = make_montecarlo_model(o)->render(one.ctx());
        if (test::world_rank() != 0) continue;
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 6; ++x) {
                const double a = all.pixel(x, y)[b], s1 = single.pixel(x, y)[0];
                EXPECT_NEAR(a, s1, 1e-6 * s1) << "band " << b << " pixel " << x << "," << y;
                EXPECT_NEAR(all.stderr_rgb[static_cast<size_t>(y * 6 + x) * 3 + b],
                            single.stderr_rgb[static_cast<size_t>(y * 6 + x) * 3], 1e-6 * s1);
            }
    }
}

TEST(MonteCarloModel, ImageIndependentOfRankCount) {
    World world(MPI_COMM_WORLD, 0.95), self(MPI_COMM_SELF, 0.95);
    MonteCarloOptions o;
    o.image = true;
    o.samples_per_pixel = 16;
    const Image a = make_montecarlo_model(o)->render(world.ctx());
    const Image b = make_montecarlo_model(o)->render(self.ctx());
    if (test::world_rank() != 0) return;
    ASSERT_EQ(a.rgba.size(), b.rgba.size());
    double worst = 0.0, peak = 0.0;
    for (size_t i = 0; i < a.rgba.size(); ++i) {
        worst = std::max(worst, static_cast<double>(std::abs(a.rgba[i] - b.rgba[i])));
        peak = std::max(peak, static_cast<double>(b.rgba[i]));
    }
    EXPECT_GT(peak, 0.0);
    // Whole pixels per rank, each summed in sample order (path_tracer.h): identical.
    EXPECT_EQ(worst, 0.0);
    EXPECT_EQ(a.stderr_rgb, b.stderr_rgb);
}

}  // namespace
}  // namespace nimbus
