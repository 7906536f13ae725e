// The scene's volume sources ([[sources]]) in the ray caster's physical modes: a covered cell
// with density adds q_b = power_b / 4π to the view source J_b (source_kernel.h).
//  - Alone (no lights, no diffuse light) on a medium of density rho0 with holes, a source over
//    the whole domain gives J = q where rho = rho0 and 0 in the holes: exactly the particle
//    model (emission_absorption, J = C kappa, analytic_modes_test.cpp) with C_b = q_b / kappa_b,
//    so the two images agree to float rounding, on 1 and 2 ranks; also with periodic x/y, where
//    the ghost cells across the periodic faces must emit like the cells they wrap to.
//  - With the sun and a diffuse field, the image is the sum of the images of the light alone
//    and of the source alone (background 0): the emission adds to the scattered light.
#include <gtest/gtest.h>

#include <numbers>

#include "tests/support/mpi_test.h"
#include "tests/unit/render/render_fixture.h"

namespace nimbus {
namespace {

constexpr double kRho0 = 0.9;

Scene base_scene(const Grid& g) {
    Scene s;
    s.grid.n = {g.n[0], g.n[1], g.n[2]};
    s.grid.cell_size = g.h;  // unit m
    s.bands = {BandOptics{"r", 0.5, 0.3, 0.8}, BandOptics{"g", 1.0, 0.6, 0.8}, BandOptics{"b", 2.0, 0.9, 0.8}};
    test::oblique_camera(s);
    return s;
}

Grid grid16() {
    Grid g;
    g.n = {16, 16, 16};
    g.h = 0.1;
    return g;
}

// rho0 inside the domain except for a sparse pattern of empty cells; empty outside.
double holey(const Int3& n, int i, int j, int k) {
    if (!test::inside_domain(n, i, j, k)) return 0.0;
    return (i * 7 + j * 3 + k) % 5 == 0 ? 0.0 : kRho0;
}

// A source over the whole domain on the holey medium, rendered in the scattering mode without
// lights, against the particle model with C_b = q_b / kappa_b: equal to float rounding. With
// periodic x/y the ghost cells across those faces are wrapped domain cells, and they emit too
// (a ghost that did not would halve J in the half cell next to each periodic face).
void expect_source_equals_particle_model(std::array<bool, 3> periodic) {
    const Grid g = grid16();
    Scene src = base_scene(g);
    src.render.mode = RenderMode::scattering;
    src.background.color = {0.1, 0.2, 0.3};
    const std::vector<double> power = {3.0, 1.5, 0.7};  // W/m³ per band
    src.sources = {SourceSpec{{0.0, 0.0, 0.0}, {1.6, 1.6, 1.6}, power}};

    Scene particle = base_scene(g);
    particle.render.mode = RenderMode::emission_absorption;
    particle.background.color = src.background.color;
    particle.render.emission_color.clear();
    for (size_t b = 0; b < 3; ++b)
        particle.render.emission_color.push_back(power[b] / (4 * std::numbers::pi) / (kRho0 * src.bands[b].sigma_t));

    auto wrap = [&](int a, int c) { return periodic[static_cast<size_t>(a)] ? (c + g.n[a]) % g.n[a] : c; };
    auto w = test::make_world(
        MPI_COMM_WORLD, g, src, [&](int i, int j, int k) { return holey(g.n, wrap(0, i), wrap(1, j), wrap(2, k)); },
        {0, 0, 0}, periodic);
    const Image a = test::render(src, w), b = test::render(particle, w);
    if (test::world_rank() != 0) return;
    int glowing = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x)
            for (int c = 0; c < 4; ++c) {
                EXPECT_TRUE(test::close_rel(a.pixel(x, y)[c], b.pixel(x, y)[c], 1e-6))
                    << "pixel " << x << "," << y << " channel " << c << ": " << a.pixel(x, y)[c] << " vs "
                    << b.pixel(x, y)[c];
                glowing += c == 0 && a.pixel(x, y)[0] > 1.5 * src.background.color[0];
            }
    EXPECT_GT(glowing, 200);  // the emission shows
}

TEST(RenderEmission, VolumeSourceEqualsTheParticleModel) { expect_source_equals_particle_model({false, false, false}); }

TEST(RenderEmission, PeriodicGhostCellsEmit) { expect_source_equals_particle_model({true, true, false}); }

TEST(RenderEmission, SourceAddsToTheScatteredLight) {
    const Grid g = grid16();
    Scene lit = base_scene(g);
    lit.render.mode = RenderMode::scattering;
    lit.background.color = {0.0, 0.0, 0.0};
    Scene glowing = lit, both = lit;
    // A source over part of the domain (cell centres with x < 0.8, z >= 0.3).
    const SourceSpec box{{0.0, 0.0, 0.3}, {0.8, 1.6, 1.6}, {2.0, 1.0, 0.5}};
    both.sources = {box};
    glowing.sources = {box};

    const Vec3 sun = normalized(Vec3{0.4, 0.2, -1.0});
    auto with_light = [&](bool on) {
        auto w = test::make_world(MPI_COMM_WORLD, g, lit, [&](int i, int j, int k) { return holey(g.n, i, j, k); });
        if (on) {
            w.light.lights = {DirectionalLight{"sun", sun, {2.0, 1.5, 1.0}}};
            w.light.tau_rho.push_back(test::make_field(*w.d, [&](int i, int j, int k, int) {
                return kRho0 * (g.upper().z - g.center(i, j, k).z) / std::abs(sun.z);
            }));
            for (int b = 0; b < 3; ++b) {
                w.diffuse.fluence[static_cast<size_t>(b)] =
                    test::make_field(*w.d, [&](int i, int, int k, int) { return 0.2 + 0.05 * b + 0.01 * (i - k); });
            }
        } else {
            w.light.lights = {DirectionalLight{"sun", sun, {0.0, 0.0, 0.0}}};
            w.light.tau_rho.push_back(test::make_field(*w.d, [](int, int, int, int) { return 0.0; }));
        }
        return w;
    };
    const auto lit_world = with_light(true), dark_world = with_light(false);
    const Image I_light = test::render(lit, lit_world), I_both = test::render(both, lit_world),
                I_source = test::render(glowing, dark_world);
    if (test::world_rank() != 0) return;
    double source_part = 0.0;
    for (int y = 0; y < I_both.height; ++y)
        for (int x = 0; x < I_both.width; ++x)
            for (int c = 0; c < 3; ++c) {
                const double want = I_light.pixel(x, y)[c] + I_source.pixel(x, y)[c];
                EXPECT_TRUE(test::close_rel(I_both.pixel(x, y)[c], want, 1e-5))
                    << "pixel " << x << "," << y << " band " << c << ": " << I_both.pixel(x, y)[c] << " vs " << want;
                source_part += I_source.pixel(x, y)[c];
            }
    EXPECT_GT(source_part, 1.0);  // the source is seen
}

}  // namespace
}  // namespace nimbus
