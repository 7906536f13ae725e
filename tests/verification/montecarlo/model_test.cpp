// The Monte Carlo model through the ScatteringModel interface: solve() fills fluence and its
// standard error and reports its figures of merit; render() path-traces the camera image
// (pure absorber: each sample sees the background with probability T, so the pixel mean is
// background x (1 - alpha)); the image does not depend on the rank count.
#include <gtest/gtest.h>

#include <cmath>

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
    World(MPI_Comm comm, double albedo) : d(comm, {8, 8, 8}) {
        scene.grid.n = {8, 8, 8};
        scene.camera.position = {0.5, 0.5, 3.0};
        scene.camera.look_at = {0.5, 0.5, 0.0};
        scene.camera.up = {0, 1, 0};
        scene.camera.fov_deg = 1.0;
        scene.camera.width = 6;
        scene.camera.height = 4;
        scene.background.color = {0.5};
        m.grid.n = {8, 8, 8};
        m.grid.h = 1.0;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) { m.rho(i, j, k) = 0.5 + 0.1 * ((i + 2 * j + k) % 3); });
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

TEST(MonteCarloModel, AbsorberImageIsBackgroundTimesTransmittance) {
    World w(MPI_COMM_WORLD, 0.0);
    MonteCarloOptions o;
    o.image = true;
    o.samples_per_pixel = 4000;
    auto model = make_montecarlo_model(o);
    ASSERT_TRUE(model->renders_image());
    const Image img = model->render(w.ctx());
    if (test::world_rank() != 0) {
        EXPECT_TRUE(img.empty());
        return;
    }
    ASSERT_EQ(img.width, 6);
    double z2 = 0.0;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x) {
            const float* p = img.pixel(x, y);
            const double expect = 0.5 * (1.0 - p[3]);
            EXPECT_GT(p[3], 0.7);  // tau = 0.3 * (0.5..0.7) * 8 ≈ 1.44 straight down: T ≈ 0.24
            EXPECT_LT(p[3], 0.8);
            const double se = img.stderr_rgb[static_cast<size_t>(y * 6 + x) * 3];
            const double z = (p[0] - expect) / se;
            z2 += z * z;
            EXPECT_LT(std::abs(z), 4.0);
            EXPECT_EQ(p[0], p[1]);
        }
    const double rms = std::sqrt(z2 / 24.0);
    EXPECT_LT(rms, 1.6);
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
    EXPECT_LE(worst, 1e-6 * peak);
}

}  // namespace
}  // namespace nimbus
