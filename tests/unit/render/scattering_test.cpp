// Single scattering in a homogeneous slab (the whole domain, rho = 1, extended into the outer
// ghost layer) lit by a sun along w, against the closed form for a straight chord. With
// tau_rho(x) = rho (z_top - z) / |w_z| (the exact depth to the slab top along -w) and a view
// ray entering at height z_e, the sun's optical depth along the ray is u0 + beta s with
//   u0 = kappa (z_top - z_e)/|w_z|,  beta = -kappa d_z / |w_z|,
// so Max 1995 eq. 14 with J = kappa a E0 e^{-u0 - beta s} p(mu) (+ the diffuse term) gives
//   I = I0 e^{-kappa L} + kappa a E0 p(mu) e^{-u0} (1 - e^{-(kappa + beta) L}) / (kappa + beta)
//     + a [Phi/(4π) + (3g/4π) F·(-d)] (1 - e^{-kappa L}),      mu = w·(-d),
// for a constant diffuse fluence Phi and flux F. single_unshadowed drops e^{-u0 - beta s}
// and the diffuse term. Trilinear reconstruction of J between cell centres and the step rule
// are second order in the cell optical depth (kappa h = 0.031 here) inside the domain; in the
// half cell between a face cell's centre and the domain's face the ray caster holds the face
// cell's values (its ghosts repeat the face cell, view_volume.cpp, whatever the ghosts given
// here hold), which is first order there: J changes by kappa h / (2 |w_z|) = 1.7% (the sun's
// depth; the phase angle adds less) across that half cell, about 1/60 of a chord, at entry and
// exit. Measured max relative error 5.0e-4 (shadowed), 2.2e-4 (unshadowed; 6.0e-5 and 3.2e-5
// with J continued linearly into the ghosts), checked at 1e-3 and 4.5e-4.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>

#include "src/physics/phase.h"
#include "src/render/source_kernel.h"
#include "tests/support/mpi_test.h"
#include "tests/unit/render/render_fixture.h"

namespace nimbus {
namespace {

struct SlabCase {
    Grid grid;
    Scene scene;
    Vec3 w;
    double E0 = 2.0, rho = 1.0, Phi = 0.6;
    Vec3 F{0.05, -0.02, 0.1};
};

SlabCase make_case(RenderMode mode) {
    SlabCase c;
    c.grid.n = {32, 32, 32};
    c.grid.h = 1.0 / 32;
    c.scene.bands = {BandOptics{"gray", 1.0, 0.8, 0.5}};
    c.scene.render.mode = mode;
    c.scene.background.color = {0.05};
    c.scene.camera.position = {0.5, -1.2, 1.6};
    c.scene.camera.look_at = {0.5, 0.5, 0.4};
    c.scene.camera.fov_deg = 50;
    c.scene.camera.width = 32;
    c.scene.camera.height = 24;
    c.w = normalized(Vec3{0.4, 0.2, -1.0});
    return c;
}

void check_slab(RenderMode mode) {
    const SlabCase c = make_case(mode);
    const bool shadows = mode == RenderMode::scattering;
    auto w = test::make_world(MPI_COMM_WORLD, c.grid, c.scene, [&](int, int, int) { return c.rho; });
    const double z_top = c.grid.upper().z, wz = std::abs(c.w.z);
    w.light.lights = {DirectionalLight{"sun", c.w, {c.E0}}};
    w.light.tau_rho.push_back(test::make_field(*w.d, [&](int i, int j, int k, int) {
        return c.rho * (z_top - c.grid.center(i, j, k).z) / wz;
    }));
    w.diffuse.fluence = {test::make_field(*w.d, [&](int, int, int, int) { return c.Phi; })};
    w.diffuse.flux = {test::make_field(*w.d, [&](int, int, int, int comp) { return c.F[comp]; }, 3)};
    const Image image = test::render(c.scene, w);
    if (test::world_rank() != 0) return;

    const Camera cam(c.scene.camera, c.grid);
    const BandOptics& o = c.scene.bands[0];
    const double kappa = c.rho * o.sigma_t, I0 = c.scene.background.color[0];
    double max_err = 0;
    int hits = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const Vec3 d = cam.pixel_direction(x, y), org = cam.position();
            double t0, t1, want = I0;
            if (test::chord(org, d, c.grid.origin, c.grid.upper(), t0, t1)) {
                ++hits;
                const double L = t1 - t0, ext = std::exp(-kappa * L);
                const double p = hg_phase(o.g, dot(c.w, -d));
                const double z_e = org.z + t0 * d.z;
                const double u0 = shadows ? kappa * (z_top - z_e) / wz : 0.0;
                const double beta = shadows ? -kappa * d.z / wz : 0.0;
                const double k_eff = kappa + beta;
                const double path = std::abs(k_eff * L) < 1e-12 ? L : (1 - std::exp(-k_eff * L)) / k_eff;
                want = I0 * ext + kappa * o.albedo * c.E0 * p * std::exp(-u0) * path;
                if (shadows) {
                    const double inv4pi = 0.25 / std::numbers::pi;
                    want += o.albedo * (c.Phi * inv4pi + 3 * o.g * inv4pi * dot(c.F, -d)) * (1 - ext);
                }
            }
            const double got = image.pixel(x, y)[0];
            max_err = std::max(max_err, std::abs(got - want) / want);
            EXPECT_TRUE(test::close_rel(got, want, shadows ? 1e-3 : 4.5e-4))
                << "pixel " << x << "," << y << ": " << got << " vs " << want;
        }
    EXPECT_GT(hits, 250);
    std::cout << "[ slab ] " << to_string(mode) << ": max relative error " << max_err << " over "
              << hits << " rays\n";
}

// The P1 in-scatter U + (3g/4π) F·w: unchanged while the flux is small enough for it to be >= 0
// in every direction; beyond that its F term is scaled to the bound, so it is >= 0 everywhere,
// touches 0 opposite the flux, and keeps U as its mean over directions (a quadrature over a
// Fibonacci sphere of 2000 directions; the mean of F·w over the sphere is 0).
TEST(RenderScattering, DiffuseInscatterStaysNonNegativeWithItsMean) {
    const double inv4pi = 0.25 / std::numbers::pi, fluence = 2.0, U = fluence * inv4pi;
    const Vec3 dir = normalized(Vec3{0.3, -0.5, 0.8});
    for (double g : {0.85, -0.6}) {
        const double bound = U / (3.0 * std::abs(g) * inv4pi);  // the largest |F| left as it is
        for (double f : {0.5, 0.999, 2.0, 50.0}) {
            const Vec3 F = dir * (f * bound);
            double mean = 0.0, least = 1e300;
            const int n = 2000;
            for (int i = 0; i < n; ++i) {
                const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z), phi = 2.399963229728653 * i;
                const Vec3 w{r * std::cos(phi), r * std::sin(phi), z};
                const double J = diffuse_inscatter(fluence, g, true, F, w);
                if (f < 1.0) {
                    EXPECT_NEAR(J, U + 3.0 * g * inv4pi * dot(F, w), 1e-15);
                }
                mean += J / n;
                least = std::min(least, J);
            }
            EXPECT_NEAR(mean, U, 1e-3 * U) << "g " << g << " |F| / bound " << f;
            EXPECT_GE(least, 0.0) << "g " << g << " |F| / bound " << f;
            const double opposite = diffuse_inscatter(fluence, g, true, F, g > 0 ? -dir : dir);
            EXPECT_NEAR(opposite, f < 1.0 ? U * (1.0 - f) : 0.0, 1e-12) << "g " << g << " |F| / bound " << f;
        }
    }
    EXPECT_EQ(diffuse_inscatter(fluence, 0.85, false, Vec3{1e3, 0, 0}, Vec3{-1, 0, 0}), U);
}

TEST(RenderScattering, SingleScatterWithShadowsInASlab) { check_slab(RenderMode::scattering); }
TEST(RenderScattering, SingleScatterUnshadowedInASlab) { check_slab(RenderMode::single_unshadowed); }

}  // namespace
}  // namespace nimbus
