// Decomposition invariance and an independent reference march on a procedural cumulus.
//  * The full scattering image (3 bands, sun + sky light terms, diffuse fluence and flux,
//    lit ground) rendered on the world communicator (slabs along z, and split along x) equals
//    the one rendered on MPI_COMM_SELF with the whole medium, to 1e-5 relative.
//  * emission_absorption on a cumulus with empty regions (so empty-block skipping is used)
//    equals a brute-force march written here: same step lattice (chord cut into
//    ceil(L / (step h)) equal steps, sampled at midpoints), trilinear rho with 0 outside the
//    domain, every step sampled, exact per-step integration, to 1e-5 relative.
//  * Early termination (march.h) moves each pixel by at most render.early_termination of its own
//    radiance (+ float32 rounding), on the world communicator and alone: a dim glowing cube
//    with a source 10^7 times brighter hidden 15-20 optical depths inside (where cutting every
//    ray at T < 1e-6 loses up to 82% of a pixel), and a glowing layer before an absorber with
//    a bright sky behind and a near-empty cell (3 bands); the bound's value is checked too.
#include <gtest/gtest.h>

#include <iostream>
#include <numbers>

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

// Early termination against the uncut march (eps = 0, one rank), per pixel and band: on the
// world communicator and alone, every pixel within eps of its radiance plus the float32 floor
// of compositing (march.h's bound). Returns the run's report values for the caller's checks.
struct CutRun {
    long samples_cut = 0, samples_uncut = 0;
    nlohmann::json render;
};

template <class Rho>
CutRun expect_cut_within_eps(const Scene& s, Rho&& rho, const Image* without = nullptr,
                             int* lit_through = nullptr) {
    constexpr double eps = 1e-6, kFloat32Floor = 3e-7;
    const Grid g = make_grid(s.grid);
    CutRun out;
    auto render = [&](MPI_Comm comm, double e, long& samples) {
        Scene sc = s;
        sc.render.early_termination = e;
        const auto w = test::make_world(comm, g, sc, rho);
        Report report;
        const Image image = render_image(RenderInputs{sc, w.medium, w.light, w.diffuse}, *w.d, report);
        samples = report.values()["render"]["samples"].get<long>();  // rank 0's sum
        out.render = report.values()["render"];
        return image;
    };
    long n_world = 0;
    const Image exact = render(MPI_COMM_SELF, 0.0, out.samples_uncut);
    const Image world = render(MPI_COMM_WORLD, eps, n_world);
    const Image self = render(MPI_COMM_SELF, eps, out.samples_cut);
    if (test::world_rank() != 0) return out;
    double max_world = 0, max_self = 0;
    for (int y = 0; y < exact.height; ++y)
        for (int x = 0; x < exact.width; ++x)
            for (int c = 0; c < s.nbands(); ++c) {
                const double want = exact.pixel(x, y)[c];
                if (!(want > 0)) continue;
                if (without && c == 0 && want > 1.05 * without->pixel(x, y)[0]) ++*lit_through;
                max_world = std::max(max_world, std::abs(world.pixel(x, y)[c] - want) / want);
                max_self = std::max(max_self, std::abs(self.pixel(x, y)[c] - want) / want);
                EXPECT_TRUE(test::close_rel(world.pixel(x, y)[c], want, eps + kFloat32Floor)) << x << "," << y << " c" << c;
                EXPECT_TRUE(test::close_rel(self.pixel(x, y)[c], want, eps + kFloat32Floor)) << x << "," << y << " c" << c;
            }
    EXPECT_LT(out.samples_cut, out.samples_uncut);  // the cut does save steps
    std::cout << "[ early termination ] max relative change " << max_world << " (" << test::world_size()
              << " ranks), " << max_self << " (1 rank); samples " << out.samples_cut << " of "
              << out.samples_uncut << "\n";
    return out;
}

// Looking down at the front face y = 0 of a 24³ cube: the rays cross the z slab boundaries.
Scene cube_scene() {
    Scene s;
    s.grid.n = {24, 24, 24};
    s.grid.cell_size = 0.1;
    s.render.mode = RenderMode::scattering;
    s.background.color = {0.0};
    s.camera.position = {0.5, -1.5, 1.5};
    s.camera.look_at = {0.5, 0.5, 0.5};
    s.camera.fov_deg = 25;
    s.camera.width = 64;
    s.camera.height = 48;
    return s;
}

// A cube of optical thickness 1.5 per cell glowing weakly everywhere (q1) and 10^7 times more
// strongly in 6³ central cells (across the slab boundary of 2 ranks). No lights, no diffuse
// field: J = q where the sources are. The hidden source shows through 15-20 optical depths;
// cutting at T < 1e-6 alone loses up to 82% of a pixel on 1 rank and adds 140% on 2.
TEST(RenderDecomposition, EarlyTerminationCutsEachPixelByAtMostItsShare) {
    Scene s = cube_scene();
    s.bands = {BandOptics{"gray", 15.0, 0.8, 0.0}};
    s.sources = {SourceSpec{{0.0, 0.0, 0.0}, {2.4, 2.4, 2.4}, {1.0}},
                 SourceSpec{{0.9, 0.9, 0.9}, {1.5, 1.5, 1.5}, {1e7}}};
    const Grid g = make_grid(s.grid);
    auto cube = [&](int i, int j, int k) { return test::inside_domain(g.n, i, j, k) ? 1.0 : 0.0; };
    Scene dim = s;  // without the hidden source
    dim.sources.pop_back();
    const auto w_dim = test::make_world(MPI_COMM_SELF, g, dim, cube);
    const Image without = test::render(dim, w_dim);
    int lit_through = 0;
    const CutRun run = expect_cut_within_eps(s, cube, &without, &lit_through);
    if (test::world_rank() != 0) return;
    EXPECT_GT(lit_through, 50);  // the hidden source adds more than 5% to many pixels
    // B = 2 S, S = the hidden source's q / kappa (J >= 0 everywhere; march.h).
    const double S = 1e7 / (4 * std::numbers::pi) / 15.0;
    EXPECT_NEAR(run.render["termination_bound"][0].get<double>(), 2 * S, 1e-6 * S);
}

// Three bands (the float lanes of the march), a glowing front layer (3 cells) before 21 cells
// of absorber (2-3 optical depths per cell), a sky 1000 times brighter than the glow behind
// it, and one cell of density 1e-30 in the glowing layer, whose J / kappa is 10^30 times the
// others': the bound must count the sky (without it, S is the thin cell's q L, 12 times
// smaller in band r, and pixels move by up to 6e-6) and must stay finite (J / max(kappa, 1/L):
// with J / kappa it is infinite and no ray is ever cut).
TEST(RenderDecomposition, EarlyTerminationCountsTheSkyBehindAndThinCells) {
    Scene s = cube_scene();
    s.bands = {BandOptics{"r", 20.0, 0.8, 0.0}, BandOptics{"g", 25.0, 0.8, 0.0}, BandOptics{"b", 30.0, 0.8, 0.0}};
    s.sources = {SourceSpec{{0.0, 0.0, 0.0}, {2.4, 0.3, 2.4}, {1.0, 2.0, 3.0}}};
    const double q = 1.0 / (4 * std::numbers::pi);  // the glow's J / kappa is q / 20 in every band
    s.background.color = {1000 * q / 20, 1000 * q / 20, 1000 * q / 20};
    const Grid g = make_grid(s.grid);
    auto rho = [&](int i, int j, int k) {
        if (!test::inside_domain(g.n, i, j, k)) return 0.0;
        return i == 3 && j == 1 && k == 20 ? 1e-30 : 1.0;
    };
    const CutRun run = expect_cut_within_eps(s, rho);
    if (test::world_rank() != 0) return;
    // S = max(sky, the thin cell's q_b L) with L = sqrt(3) 2.4 m, the domain's diagonal.
    const double L = std::sqrt(3.0) * 2.4;
    for (int b = 0; b < 3; ++b) {
        const double S = std::max(1000 * q / 20, (b + 1) * q * L);
        EXPECT_NEAR(run.render["termination_bound"][b].get<double>(), 2 * S, 1e-6 * S) << "band " << b;
    }
}

}  // namespace
}  // namespace nimbus
