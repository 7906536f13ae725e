// Decomposition invariance and an independent reference march on a procedural cumulus.
//  * The full scattering image (3 bands, sun + sky light terms, diffuse fluence and flux,
//    lit ground) rendered on the world communicator (slabs along z, and split along x) equals
//    the one rendered on MPI_COMM_SELF with the whole medium, to 1e-5 relative.
//  * emission_absorption on a cumulus with empty regions (so empty-block skipping is used)
//    equals a brute-force march written here: same step lattice (chord cut into
//    ceil(L / (step h)) equal steps, sampled at midpoints), trilinear rho with 0 outside the
//    domain, every step sampled, exact per-step integration, to 1e-5 relative.
//  * Early termination (march.h) moves each pixel by at most render.early_termination of its own
//    radiance, on the world communicator and alone: a dim glowing cube with a source 10^7 times
//    brighter hidden 15-30 optical depths inside (transmittance < 1e-6 on the way in), where
//    cutting every ray at T < 1e-6 loses the hidden source's ~10% share of the pixels.
#include <gtest/gtest.h>

#include <iostream>

#include "src/physics/lights.h"
#include "tests/support/mpi_test.h"
#include "tests/unit/render/render_fixture.h"

namespace nimbus {
namespace {

Scene cumulus_scene() {
    Scene s;
    s.grid.n = {24, 24, 24};
    s.grid.cell_size = 0.25;
    s.bands = {BandOptics{"r", 0.6, 0.9, 0.8}, BandOptics{"g", 0.8, 0.92, 0.7},
               BandOptics{"b", 1.0, 0.95, 0.6}};
    s.sun.direction = normalized(Vec3{0.3, 0.2, -1.0});
    s.sun.irradiance = {1.0, 1.1, 1.2};
    s.sky.radiance = {0.05, 0.07, 0.1};
    s.sky.directions = 3;
    s.render.mode = RenderMode::scattering;
    s.background.kind = BackgroundSpec::Kind::ground;
    s.background.ground_color = {0.3, 0.4, 0.5};
    s.background.color = {0.1, 0.15, 0.2};
    s.camera.position = {1.3, -0.6, 1.2};
    s.camera.look_at = {0.5, 0.5, 0.3};
    s.camera.fov_deg = 60;
    s.camera.width = 32;
    s.camera.height = 24;
    return s;
}

// The medium, light transport and diffuse field of cumulus_scene on one decomposition; every
// field is a pure function of the global cell, as a light pass and a solver would deliver it.
test::RenderWorld cumulus_world(MPI_Comm comm, const Scene& s, const Int3& proc_dims) {
    const Grid g = make_grid(s.grid);
    const ProceduralDensity density(s.medium, g.n);
    auto w = test::make_world(comm, g, s, [&](int i, int j, int k) {
        return test::inside_domain(g.n, i, j, k) ? density(i, j, k) : 0.0;
    }, proc_dims);
    w.light.lights = make_lights(s);
    for (size_t l = 0; l < w.light.lights.size(); ++l)
        w.light.tau_rho.push_back(test::make_field(*w.d, [&](int i, int j, int k, int) {
            return 0.1 * (24 - k) + 0.02 * static_cast<double>(l) * i + 0.01 * j;
        }));
    w.diffuse.fluence.clear();
    for (int b = 0; b < s.nbands(); ++b) {
        w.diffuse.fluence.push_back(test::make_field(*w.d, [&](int i, int j, int k, int) {
            return 0.5 + 0.01 * (i + j + k) + 0.1 * b;
        }));
        w.diffuse.flux.push_back(test::make_field(*w.d, [&](int i, int j, int k, int c) {
            return 0.002 * ((c == 0 ? i : c == 1 ? j : k) - 12);
        }, 3));
    }
    return w;
}

void compare_with_self(const Int3& world_dims) {
    const Scene s = cumulus_scene();
    const Image world = test::render(s, cumulus_world(MPI_COMM_WORLD, s, world_dims));
    // Every rank renders the whole medium alone (collective only over itself).
    const Image self = test::render(s, cumulus_world(MPI_COMM_SELF, s, {0, 0, 0}));
    if (test::world_rank() != 0) return;
    ASSERT_EQ(world.rgba.size(), self.rgba.size());
    double max_rel = 0, sum = 0;
    int opaque = 0;
    for (int y = 0; y < s.camera.height; ++y)
        for (int x = 0; x < s.camera.width; ++x) {
            const float* a = world.pixel(x, y);
            const float* b = self.pixel(x, y);
            for (int c = 0; c < 3; ++c) {
                max_rel = std::max(max_rel, std::abs(double(a[c]) - b[c]) / std::abs(double(b[c])));
                EXPECT_TRUE(test::close_rel(a[c], b[c], 1e-5)) << x << "," << y << " c" << c << ": "
                                                              << a[c] << " vs " << b[c];
                sum += b[c];
            }
            EXPECT_NEAR(a[3], b[3], 1e-6);
            opaque += b[3] > 0.5;
        }
    EXPECT_GT(opaque, 20);  // the cloud is really in the picture
    EXPECT_GT(sum, 0.0);
    std::cout << "[ decomposition ] " << test::world_size() << " ranks as " << world_dims[0] << "x"
              << world_dims[1] << "x" << world_dims[2] << ": max relative difference " << max_rel << "\n";
}

TEST(RenderDecomposition, WorldEqualsSelfSlabsAlongZ) { compare_with_self({0, 0, 0}); }
TEST(RenderDecomposition, WorldEqualsSelfSplitAlongX) { compare_with_self({0, 1, 1}); }

// Brute-force reference for emission_absorption with rho trilinear between cell centres.
TEST(RenderDecomposition, MatchesBruteForceMarchThroughEmptySpace) {
    Scene s;
    s.grid.n = {32, 32, 32};
    s.grid.cell_size = 0.2;
    s.bands = {BandOptics{"gray", 1.0, 0.9, 0.8}};
    s.render.mode = RenderMode::emission_absorption;
    s.render.emission_color = {0.7};
    s.render.early_termination = 0.0;
    s.render.step = 0.7;
    s.background.color = {0.2};
    s.camera.position = {1.2, -0.8, 0.9};
    s.camera.look_at = {0.5, 0.5, 0.4};
    s.camera.fov_deg = 45;
    s.camera.width = 32;
    s.camera.height = 24;
    const Grid g = make_grid(s.grid);
    const ProceduralDensity density(s.medium, g.n);
    std::vector<double> rho(static_cast<size_t>(g.cells()));
    for_each_cell(g.box(), [&](int i, int j, int k) {
        rho[static_cast<size_t>((k * g.n[1] + j) * g.n[0] + i)] = density(i, j, k);
    });
    auto rho_at = [&](int i, int j, int k) {
        return test::inside_domain(g.n, i, j, k) ? rho[static_cast<size_t>((k * g.n[1] + j) * g.n[0] + i)] : 0.0;
    };
    const auto w = test::make_world(MPI_COMM_WORLD, g, s, rho_at);
    const Image image = test::render(s, w);
    if (test::world_rank() != 0) return;

    const Camera cam(s.camera, g);
    const double C = 0.7, I0 = 0.2;
    double max_rel = 0;
    int cloudy = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const Vec3 o = cam.position(), d = cam.pixel_direction(x, y);
            double t0, t1, T = 1, I = 0;
            if (test::chord(o, d, g.origin, g.upper(), t0, t1)) {
                const int n = std::max(1, static_cast<int>(std::ceil((t1 - t0) / (s.render.step * g.h))));
                const double ds = (t1 - t0) / n;
                for (int m = 0; m < n; ++m) {
                    const Vec3 p = o + d * (t0 + (m + 0.5) * ds);
                    double c[3];
                    int i0[3];
                    for (int a = 0; a < 3; ++a) {
                        c[a] = (p[a] - g.origin[a]) / g.h - 0.5;
                        i0[a] = static_cast<int>(std::floor(c[a]));
                        c[a] -= i0[a];
                    }
                    double r = 0;
                    for (int corner = 0; corner < 8; ++corner) {
                        const int dx = corner & 1, dy = (corner >> 1) & 1, dz = corner >> 2;
                        r += (dx ? c[0] : 1 - c[0]) * (dy ? c[1] : 1 - c[1]) * (dz ? c[2] : 1 - c[2]) *
                             rho_at(i0[0] + dx, i0[1] + dy, i0[2] + dz);
                    }
                    const double e = std::exp(-r * s.bands[0].sigma_t * ds);
                    I += T * C * (1 - e);
                    T *= e;
                }
            }
            const double want = I + I0 * T;
            cloudy += T < 0.9;
            max_rel = std::max(max_rel, std::abs(image.pixel(x, y)[0] - want) / want);
            EXPECT_TRUE(test::close_rel(image.pixel(x, y)[0], want, 1e-5))
                << x << "," << y << ": " << image.pixel(x, y)[0] << " vs " << want;
            EXPECT_NEAR(image.pixel(x, y)[3], 1 - T, 1e-6);
        }
    EXPECT_GT(cloudy, 50);
    std::cout << "[ brute force ] max relative difference " << max_rel << "\n";
}

// A cube of optical thickness 1.5 per cell glowing weakly everywhere (q1) and 10^7 times more
// strongly in 6³ central cells (across the slab boundary of 2 ranks). No lights, no diffuse field:
// J = q where the sources are. The hidden source shows through 15-20 optical depths.
TEST(RenderDecomposition, EarlyTerminationCutsEachPixelByAtMostItsShare) {
    Scene s;
    s.grid.n = {24, 24, 24};
    s.grid.cell_size = 0.1;
    s.bands = {BandOptics{"gray", 15.0, 0.8, 0.0}};
    s.render.mode = RenderMode::scattering;
    s.background.color = {0.0};
    s.sources = {SourceSpec{{0.0, 0.0, 0.0}, {2.4, 2.4, 2.4}, {1.0}},
                 SourceSpec{{0.9, 0.9, 0.9}, {1.5, 1.5, 1.5}, {1e7}}};
    // Looking down at the front face: the rays to the hidden source cross the z slab boundary.
    s.camera.position = {0.5, -1.5, 1.5};
    s.camera.look_at = {0.5, 0.5, 0.5};
    s.camera.fov_deg = 25;
    s.camera.width = 64;
    s.camera.height = 48;
    const Grid g = make_grid(s.grid);
    auto cube = [&](int i, int j, int k) { return test::inside_domain(g.n, i, j, k) ? 1.0 : 0.0; };
    auto render = [&](MPI_Comm comm, double eps, long& samples) {
        Scene sc = s;
        sc.render.early_termination = eps;
        const auto w = test::make_world(comm, g, sc, cube);
        Report report;
        const Image image = render_image(RenderInputs{sc, w.medium, w.light, w.diffuse}, *w.d, report);
        samples = report.values()["render"]["samples"].get<long>();  // rank 0's sum
        return image;
    };
    long n_exact = 0, n_world = 0, n_self = 0;
    const Image exact = render(MPI_COMM_SELF, 0.0, n_exact);
    const Image world = render(MPI_COMM_WORLD, 1e-6, n_world);
    const Image self = render(MPI_COMM_SELF, 1e-6, n_self);
    Scene dim = s;  // without the hidden source: what the cut at T < 1e-6 alone would show
    dim.sources.pop_back();
    const auto w_dim = test::make_world(MPI_COMM_SELF, g, dim, cube);
    const Image without = test::render(dim, w_dim);
    if (test::world_rank() != 0) return;
    int lit_through = 0;
    double max_world = 0, max_self = 0;
    for (int y = 0; y < exact.height; ++y)
        for (int x = 0; x < exact.width; ++x) {
            const double want = exact.pixel(x, y)[0];
            if (!(want > 0)) continue;
            lit_through += want > 1.05 * without.pixel(x, y)[0];
            max_world = std::max(max_world, std::abs(world.pixel(x, y)[0] - want) / want);
            max_self = std::max(max_self, std::abs(self.pixel(x, y)[0] - want) / want);
            EXPECT_TRUE(test::close_rel(world.pixel(x, y)[0], want, 3e-6)) << x << "," << y;
            EXPECT_TRUE(test::close_rel(self.pixel(x, y)[0], want, 3e-6)) << x << "," << y;
        }
    EXPECT_GT(lit_through, 50);  // the hidden source adds more than 5% to many pixels
    EXPECT_LT(n_self, n_exact);  // and the cut does save steps
    std::cout << "[ early termination ] " << lit_through << " pixels lit through; max relative change "
              << max_world << " (" << test::world_size() << " ranks), " << max_self << " (1 rank); samples "
              << n_self << " of " << n_exact << "\n";
}

}  // namespace
}  // namespace nimbus
