// The ground background: a Lambertian plane at the domain's bottom lit by the sun,
//   L = (albedo/π) E0 |w_z| T_sun(ground),
// with T_sun = exp(-sigma_t tau_rho): inside the domain footprint from the bottom cell layer;
// outside it from the side face where the ray toward the sun enters the domain (1 when it
// misses the domain). A homogeneous absorbing layer high in the domain (cells k = 10..13 of 16)
// shadows the whole footprint by exp(-sigma_t rho D/|w_z|), and, with the sun tilted toward
// +x, a strip of ground beyond the x+ edge: there the sun ray enters the x+ face at height
// z_p and crosses the part of the layer above z_p. Without the layer nothing is shadowed.
// The camera sits below the layer looking down, so view rays that reach the ground cross
// only empty cells (view transmittance 1); rays that miss the ground see the sky colour.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "src/render/ground.h"
#include "tests/support/mpi_test.h"
#include "tests/unit/render/render_fixture.h"

namespace nimbus {
namespace {

// The unit grid of 16³ cells, and an absorption-mode scene with a ground (albedo 0.4) under a
// sky of 0.25 and one gray band of sigma_t.
Grid ground_grid() {
    Grid g;
    g.n = {16, 16, 16};
    g.h = 1.0 / 16;
    return g;
}

Scene ground_scene(double sigma_t) {
    Scene s;
    s.bands = {BandOptics{"gray", sigma_t, 0.9, 0.8}};
    s.render.mode = RenderMode::absorption;
    s.background.kind = BackgroundSpec::Kind::ground;
    s.background.ground_albedo = 0.4;
    s.background.color = {0.25};  // sky
    return s;
}

void check_ground(bool with_cloud, const Int3& proc_dims) {
    const Grid g = ground_grid();
    Scene s = ground_scene(2.0);
    s.camera.position = {0.5, -0.5, 0.3};
    s.camera.look_at = {0.5, 0.5, 0.0};
    s.camera.fov_deg = 70;
    s.camera.width = 32;
    s.camera.height = 24;
    const int k_bot = 10, k_top = 14;
    const double rho = with_cloud ? 1.0 : 0.0, E0 = 3.0;
    const Vec3 w = normalized(Vec3{0.3, 0.0, -1.0});
    auto world = test::make_world(MPI_COMM_WORLD, g, s, [&](int i, int j, int k) {
        return test::inside_domain(g.n, i, j, k) && k >= k_bot && k < k_top ? rho : 0.0;
    }, proc_dims);
    // tau_rho: density times the layer's thickness above the cell centre, along -w.
    world.light.lights = {DirectionalLight{"sun", w, {E0}}};
    world.light.tau_rho.push_back(test::make_field(*world.d, [&](int, int, int k, int) {
        const double zc = (k + 0.5) * g.h, lo = k_bot * g.h, hi = k_top * g.h;
        return rho * std::clamp(hi - std::max(zc, lo), 0.0, hi - lo) / std::abs(w.z);
    }));
    const Image image = test::render(s, world);
    if (test::world_rank() != 0) return;

    const Camera cam(s.camera, g);
    const double lit = 0.4 / std::numbers::pi * E0 * std::abs(w.z);
    const double shadow = std::exp(-2.0 * rho * (k_top - k_bot) * g.h / std::abs(w.z));
    // Outside the footprint (cells): the ray from (qx, qy, 0) along -w enters the x+ face at
    // height z_p = (qx - 16) |w_z| / w_x when qx > 16 (it moves toward -x); elsewhere it
    // misses. The ground integrates the face cells' outer half exactly and interpolates tau_rho
    // linearly between their centres where the ray reaches them, at height
    // z_c = z_p + (1/2) |w_z| / w_x: exact except within a cell of the layer's faces (z = 10, 14)
    // or the top centres, where those pixels are not checked.
    auto outside_T = [&](double qx, double qy, bool& checked) {
        checked = true;
        if (!(qx > 16.0) || qy < 0.0 || qy > 16.0) return 1.0;
        const double zp = (qx - 16.0) * std::abs(w.z) / w.x;
        if (zp > 16.0) return 1.0;
        const double zc = zp + 0.5 * std::abs(w.z) / w.x;
        if (std::abs(zc - k_bot) < 1.0 || std::abs(zc - k_top) < 1.0 || zc > 15.5) checked = false;
        const double depth = std::clamp(k_top - std::max(zp, double(k_bot)), 0.0, double(k_top - k_bot));
        return std::exp(-2.0 * rho * depth * g.h / std::abs(w.z));
    };
    int inside = 0, outside = 0, outside_shadowed = 0, sky = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const Vec3 d = cam.pixel_direction(x, y);
            const float* px = image.pixel(x, y);
            if (d.z >= 0) {  // sky: pixels above the horizon (they may cross the layer)
                if (!with_cloud) {
                    EXPECT_FLOAT_EQ(px[0], 0.25f) << x << "," << y;
                }
                ++sky;
                continue;
            }
            const double t = -cam.position().z / d.z;
            const double gx = cam.position().x + t * d.x, gy = cam.position().y + t * d.y;
            const bool in = gx >= 0 && gx < 1 && gy >= 0 && gy < 1;
            // A ground point within h/2 + 0.3 h/2 of the x- edge: its ray toward the sun
            // reaches the bottom centres' height in the outer half of the x- cells, moving
            // toward -x, so it never enters the box of the cell centres: it leaves the domain
            // through the x- face 2.2 cells up at most, far below the layer (the tau_rho given
            // here, the layer's depth everywhere, is not read).
            const bool edge = in && gx * 16.0 + 0.5 * -w.x / -w.z < 0.5;
            bool checked = true;
            const double T = edge ? 1.0 : in ? shadow : outside_T(gx * 16.0, gy * 16.0, checked);
            if (!checked) continue;
            const double want = lit * T;
            (in ? inside : outside)++;
            if (!in && T < 0.99) ++outside_shadowed;
            EXPECT_TRUE(test::close_rel(px[0], want, 1e-6)) << x << "," << y << ": " << px[0] << " vs " << want;
            EXPECT_FLOAT_EQ(px[0], px[1]);
            EXPECT_EQ(px[3], 0.0f);  // the view ray crossed no density
        }
    EXPECT_GT(inside, 100);
    EXPECT_GT(outside, 50);
    if (with_cloud) {
        EXPECT_GT(outside_shadowed, 10);  // the shadow continues past the footprint
    }
    EXPECT_GT(sky, 0);
}

// A low sun (63° from the zenith, tan = 2) beside a block (cells i < 4, all j, k = 2..5,
// rho = 1): the ground's shadow is where the ray toward the sun crosses the block. That ray from
// ground point X (cells) is at x = X - 2z, inside the block while (X - 4)/2 < z <= X/2, so its
// depth in cells of height is
//   f(X) = [min(6, X/2) - max(2, (X - 4)/2)]+,
// rising over X in [4, 8], 2 over [8, 12], falling over [12, 16]; the light pass's tau_rho at
// a bottom cell's centre (x_c, h/2) is f(x_c + 1) h / |w_z|. Ground pixels must show
// exp(-sigma_t h f(X) / |w_z|) exactly where bilinear interpolation is exact (more than a cell
// from f's kinks); looked up above X itself, the shadow sat a cell (h/2 tan) nearer the sun (43%
// too bright on the rising ramp). Pixels whose view ray crosses the block are not checked.
void check_low_sun_shadow(const Int3& proc_dims) {
    const Grid g = ground_grid();
    Scene s = ground_scene(8.0);
    s.camera.position = {0.6, 0.5, 3.0};
    s.camera.look_at = {0.6, 0.5, 0.0};
    s.camera.up = {0.0, 1.0, 0.0};
    s.camera.fov_deg = 20;
    s.camera.width = 64;
    s.camera.height = 64;
    const Vec3 w = normalized(Vec3{1.0, 0.0, -0.5});
    const double E0 = 3.0, wz = std::abs(w.z);
    auto f = [](double X) { return std::max(0.0, std::min(6.0, X / 2) - std::max(2.0, (X - 4) / 2)); };
    auto world = test::make_world(MPI_COMM_WORLD, g, s, [&](int i, int j, int k) {
        return test::inside_domain(g.n, i, j, k) && i < 4 && k >= 2 && k < 6 ? 1.0 : 0.0;
    }, proc_dims);
    world.light.lights = {DirectionalLight{"sun", w, {E0}}};
    world.light.tau_rho.push_back(test::make_field(*world.d, [&](int i, int, int k, int) {
        return k < 2 ? f(i + 0.5 + 2.0 * (k + 0.5)) * g.h / wz : 0.0;  // only the bottom layer is read
    }));
    const Image image = test::render(s, world);
    if (test::world_rank() != 0) return;
    const Camera cam(s.camera, g);
    const double lit = 0.4 / std::numbers::pi * E0 * wz;
    int checked = 0, ramp = 0, full = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const Vec3 d = cam.pixel_direction(x, y);
            const double t = -cam.position().z / d.z;
            const double X = (cam.position().x + t * d.x) * 16.0, Y = (cam.position().y + t * d.y) * 16.0;
            const float* px = image.pixel(x, y);
            if (px[3] != 0.0f || X < 0.0 || X > 16.0 || Y < 0.0 || Y > 16.0) continue;
            bool near_kink = false;
            for (double kink : {4.0, 8.0, 12.0, 16.0}) near_kink = near_kink || std::abs(X - kink) < 1.0;
            if (near_kink) continue;
            const double depth = f(X), want = lit * std::exp(-8.0 * depth * g.h / wz);
            EXPECT_TRUE(test::close_rel(px[0], want, 1e-6))
                << x << "," << y << " (ground x " << X << " cells): " << px[0] << " vs " << want;
            ++checked;
            ramp += depth > 0.0 && depth < 2.0;
            full += depth == 2.0;
        }
    EXPECT_GT(ramp, 100);
    EXPECT_GT(full, 100);
    EXPECT_GT(checked, 500);
}

// Ground points beside the domain under a low sun from over the domain (toward the light
// u = (0.7, 0.7, 0.14) normalized; tau_rho = 1 in every cell): the ray from (-0.1, 8) enters
// the x- face 0.02 cells up and reaches the bottom centres' height 2.5 cells inside, so it is
// shadowed like the cells there; the ray from (-0.1, 15.9), by the y+ corner, enters as low and
// leaves through the y+ face before that height, so it never reads tau_rho and crosses only
// outer half cells, here empty: it is lit, as a point just inside the footprint there is (it
// was shadowed by the face cell's tau: a sliver of shadow outside the footprint's corner).
TEST(RenderGround, LowRaysBesideTheFootprintCrossOnlyWhatTheyReach) {
    Grid g;
    g.n = {16, 16, 16};
    g.h = 1.0;
    Scene s;
    s.bands = {BandOptics{"gray", 1.0, 0.9, 0.8}};
    s.render.mode = RenderMode::absorption;
    s.background.kind = BackgroundSpec::Kind::ground;
    s.background.ground_albedo = 0.5;
    auto world = test::make_world(MPI_COMM_WORLD, g, s, [](int, int, int) { return 0.0; });
    const Vec3 w = -normalized(Vec3{0.7, 0.7, 0.14});
    world.light.lights = {DirectionalLight{"sun", w, {2.0}}};
    world.light.tau_rho.push_back(test::make_field(*world.d, [](int, int, int, int) { return 1.0; }));
    const RenderInputs in{s, world.medium, world.light, world.diffuse};
    const GroundShading ground(in, *world.d);
    const double lit = 0.5 / std::numbers::pi * 2.0 * -w.z;
    auto shade = [&](double x, double y, double& L) {  // straight down onto ground point (x, y)
        return ground.shade(Vec3{x, y, 5.0}, Vec3{0, 0, -1}, &L);
    };
    double L = -1.0;
    if (shade(-0.1, 8.0, L)) {
        EXPECT_NEAR(L, lit * std::exp(-1.0), 1e-12);
    }
    if (shade(-0.1, 15.9, L)) {
        EXPECT_NEAR(L, lit, 1e-12);
    }
    if (shade(0.1, 15.9, L)) {
        EXPECT_NEAR(L, lit, 1e-12);
    }
    if (shade(1.0, 8.0, L)) {
        EXPECT_NEAR(L, lit * std::exp(-1.0), 1e-12);
    }
    // Each point is shaded by exactly one rank.
    int shaded = 0;
    for (const auto& q : {std::array<double, 2>{-0.1, 8.0}, {-0.1, 15.9}, {0.1, 15.9}, {1.0, 8.0}}) shaded += shade(q[0], q[1], L);
    MPI_Allreduce(MPI_IN_PLACE, &shaded, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(shaded, 4);
}

// ∫ rho ds (cells) along the ray (x, z) + s (ux, 0, uz), uz > 0, through 16 x 16 (x, z) cells
// of constant rho(i, k), x wrapped when periodic; the ray ends where it leaves [0, 16] in x or
// z. Exact: the pieces between the x and z grid lines the ray crosses, each at its midpoint's
// cell.
double exact_depth(const std::function<double(int, int)>& rho, bool periodic, double x, double z, double ux,
                   double uz) {
    double s_end = (16.0 - z) / uz;
    if (!periodic && ux != 0.0) s_end = std::min(s_end, ((ux > 0 ? 16.0 : 0.0) - x) / ux);
    std::vector<double> s{0.0, s_end};
    for (int m = 0; m <= 16; ++m) s.push_back((m - z) / uz);
    for (int m = -64; m <= 64 && ux != 0.0; ++m) s.push_back((m - x) / ux);
    std::sort(s.begin(), s.end());
    double depth = 0.0;
    for (size_t a = 0; a + 1 < s.size(); ++a) {
        const double s0 = std::max(s[a], 0.0), s1 = std::min(s[a + 1], s_end);
        if (!(s1 > s0)) continue;
        const double sm = 0.5 * (s0 + s1);
        const int i = static_cast<int>(std::floor(x + sm * ux)), k = static_cast<int>(std::floor(z + sm * uz));
        depth += (s1 - s0) * rho(periodic ? ((i % 16) + 16) % 16 : i, k);
    }
    return depth;
}

// The ground's optical depth toward the sun must be the exact depth from the ground point (or
// from where its ray enters the domain), on the unit-cell 16³ grid, sun in the x-z plane,
// tau_rho of every cell centre exact (exact_depth), at points where tau_rho is linear between
// the centres it is interpolated from:
// - stairs in the bottom layer, rho = 1 + i/4 (k = 0), empty above, tan(zenith) = 2: tau_rho at
//   height 1/2 is the mean of a staircase over one cell, affine in x; points inside the
//   footprint (the ray crosses a line between columns in the layer's lower half) and one
//   beside it whose ray enters the x- face at height 0.2;
// - a fog layer two cells deep (rho = 1, k < 2): inside (looked up at p, the half cell below p
//   used to be left out: e^{h / (2 |w_z|)} too much light), a ray entering the x- face at
//   height 0.1 and one at 0.8 (through the face cells' outer half, then between their centres);
// - the stairs periodic along x, rho = 1 + ((i + 4) mod 16) / 4, whose jump (i = 11 -> 12) is
//   away from the points: the lower half's walk and the lookup wrap around x = 16;
// - a block (i = 8..11, k = 4..11) and the sun behind it, tan(zenith) = 2 toward -x: ground
//   beyond the x+ face, whose rays enter it at z_e = (qx - 16) / 2 and reach the face cells'
//   centre plane at z_e + 1/4; there tau_rho is linear in z over [0.25, 2.25] and
//   [8.25, 10.25] (the ray's run across the block grows and shrinks), so entries at
//   z_e in [0.5, 1.25] and [8.25, 9.25] are exact. Looked up at the entry's own height, tau_rho
//   belonged to an entry a quarter cell lower (h/2 u_z / |u_x|): the shadow's edge beyond a
//   side face sat that far off (0.057 of 0.12 in the sphere_ground scene's image).
// A point beside the domain needs the side layers of rho and tau_rho; every point is shaded by
// exactly one rank.
void check_ground_depth(const std::function<double(int, int)>& rho, bool periodic, const Vec3& u,
                        const std::vector<double>& points, const Int3& proc_dims) {
    Grid g;
    g.n = {16, 16, 16};
    g.h = 1.0;
    Scene s = ground_scene(0.7);
    auto world = test::make_world(MPI_COMM_WORLD, g, s, [&](int i, int, int k) { return rho(i, k); }, proc_dims,
                                  {periodic, false, false});
    world.light.lights = {DirectionalLight{"sun", -u, {2.0}}};  // u: toward the sun
    world.light.tau_rho.push_back(test::make_field(*world.d, [&](int i, int, int k, int) {
        return exact_depth(rho, periodic, i + 0.5, k + 0.5, u.x, u.z);
    }));
    const RenderInputs in{s, world.medium, world.light, world.diffuse};
    const GroundShading ground(in, *world.d);
    const double lit = 0.4 / std::numbers::pi * 2.0 * u.z;
    int shaded = 0;
    for (double qx : points) {
        double L = -1.0;
        if (!ground.shade(Vec3{qx, 7.3, 5.0}, Vec3{0, 0, -1}, &L)) continue;  // straight down onto (qx, 7.3)
        ++shaded;
        const bool inside = periodic || (qx >= 0.0 && qx <= 16.0);
        const double face_x = qx < 0.0 ? 0.0 : 16.0;  // beside the domain: where the ray enters it
        const double depth = inside ? exact_depth(rho, periodic, qx, 0.0, u.x, u.z)
                                    : exact_depth(rho, periodic, face_x, (face_x - qx) / u.x * u.z, u.x, u.z);
        EXPECT_GT(depth, 0.5) << qx;
        EXPECT_NEAR(L, lit * std::exp(-0.7 * depth), 1e-12 * lit) << "ground x " << qx << ", depth " << depth;
    }
    MPI_Allreduce(MPI_IN_PLACE, &shaded, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(shaded, static_cast<int>(points.size()));
}

double stairs(int i, int k) { return k == 0 ? 1.0 + 0.25 * i : 0.0; }
double fog(int, int k) { return k < 2 ? 1.0 : 0.0; }
double periodic_stairs(int i, int k) { return k == 0 ? 1.0 + 0.25 * ((i + 4) % 16) : 0.0; }
double block(int i, int k) { return i >= 8 && i < 12 && k >= 4 && k < 12 ? 1.0 : 0.0; }
const Vec3 kSunOverX = normalized(Vec3{2.0, 0.0, 1.0});

TEST(RenderGround, StairsInTheBottomLayer) {
    check_ground_depth(stairs, false, kSunOverX, {2.0, 3.3, 7.77, 11.5, -0.4}, {0, 0, 0});
}
TEST(RenderGround, FogLayerOnTheGround) { check_ground_depth(fog, false, kSunOverX, {3.3, 8.0, -0.2, -1.6}, {0, 0, 0}); }
TEST(RenderGround, PeriodicStairsWrap) {
    check_ground_depth(periodic_stairs, true, kSunOverX, {14.7, 15.0, 15.5}, {0, 0, 0});
}
TEST(RenderGround, StairsSplitAlongX) {
    check_ground_depth(stairs, false, kSunOverX, {2.0, 3.3, 7.77, 11.5, -0.4}, {0, 1, 1});
}
// The fog layer under a sun toward -x: ground points near the x- face whose ray reaches the
// bottom centres' height in the face cells' outer half (q_x in (1, 1.5)) leave through the
// face, crossing only x_p / |u_x| of fog there; they were given the face cell's centre's tau,
// whose ray crosses half a cell more (T 0.21 instead of 0.54 in the QA's case). Beyond
// q_x = 1.5 the ray enters the centres' box through its bottom, where tau_rho is linear in x
// (its ray leaves through the x- face below the fog's top up to x = 3).
TEST(RenderGround, FogBesideTheFaceTheLightLeavesThrough) {
    const Vec3 behind{-kSunOverX.x, 0.0, kSunOverX.z};
    check_ground_depth(fog, false, behind, {0.6, 0.8, 1.2, 1.4, 2.0, 2.6}, {0, 0, 0});
}
// A roof: density only in the top cell layer (k = 15), a low sun toward -x (tan 5). Ground
// points 78-79 cells beyond the x+ face: their rays enter the face within h/2 of the top (at
// z_e = 15.55 and 15.7) and leave through the top without reaching the box of the cell
// centres, crossing 1.5-2.25 cells of the top layer's upper half: their density must count
// (the top layer was not gathered and read as empty beyond the face's own cells, i = 15: tau
// half the exact value, a review finding).
double roof(int, int k) { return k == 15 ? 1.0 : 0.0; }
TEST(RenderGround, RaysUnderTheTopCrossTheRoof) {
    check_ground_depth(roof, false, normalized(Vec3{-5.0, 0.0, 1.0}), {93.75, 94.5}, {0, 0, 0});
}
TEST(RenderGround, ShadowBeyondASideFace) {
    const Vec3 behind{-kSunOverX.x, 0.0, kSunOverX.z};
    check_ground_depth(block, false, behind, {17.0, 17.6, 18.5, 32.5, 33.3, 34.5}, {0, 0, 0});
}

TEST(RenderGround, LitGroundWithoutCloud) { check_ground(false, {0, 0, 0}); }
TEST(RenderGround, LowSunShadowSitsWhereTheRayTowardTheSunCrossesTheCloud) { check_low_sun_shadow({0, 0, 0}); }
TEST(RenderGround, LowSunShadowSplitAlongX) { check_low_sun_shadow({0, 1, 1}); }
TEST(RenderGround, CloudShadowsTheFootprint) { check_ground(true, {0, 0, 0}); }
// Split along x: both ranks hold part of the bottom layer and shade their own columns.
TEST(RenderGround, CloudShadowsTheFootprintSplitAlongX) { check_ground(true, {0, 1, 1}); }

}  // namespace
}  // namespace nimbus
