// Camera: the central pixel looks at look_at, up in the world is up in the image (row 0 is
// the top), right is right, the vertical field of view spans the image height, and domain
// units map through the grid's origin and extent; project() inverts direction(). The scene's
// check that a camera sees the domain (camera_sees_domain, src/scene) agrees with this camera.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "src/core/error.h"
#include "src/render/camera.h"
#include "src/render/ray_box.h"
#include "src/scene/medium.h"

namespace nimbus {
namespace {

double angle(const Vec3& a, const Vec3& b) {
    return std::acos(std::clamp(dot(normalized(a), normalized(b)), -1.0, 1.0));
}

Grid test_grid() {
    Grid g;
    g.n = {20, 10, 40};
    g.h = 0.5;
    g.origin = {1.0, -2.0, 3.0};
    return g;  // extent 10 x 5 x 20 m
}

CameraSpec oblique_spec() {
    CameraSpec c;
    c.position = {0.9, -0.8, 0.7};
    c.look_at = {0.4, 0.5, 0.3};
    c.up = {0, 0, 1};
    c.fov_deg = 35;
    c.width = 33;
    c.height = 25;
    return c;
}

TEST(Camera, DomainUnitsMapThroughOriginAndExtent) {
    const Camera cam(oblique_spec(), test_grid());
    EXPECT_NEAR(cam.position().x, 1.0 + 0.9 * 10, 1e-12);
    EXPECT_NEAR(cam.position().y, -2.0 - 0.8 * 5, 1e-12);
    EXPECT_NEAR(cam.position().z, 3.0 + 0.7 * 20, 1e-12);
    CameraSpec metres = oblique_spec();
    metres.domain_units = false;
    metres.position = {4, 5, 6};
    const Camera m(metres, test_grid());
    EXPECT_EQ(m.position().x, 4.0);
    EXPECT_EQ(m.position().z, 6.0);
    EXPECT_EQ(m.look_at().y, 0.5);
}

TEST(Camera, CentralPixelLooksAtLookAt) {
    const Camera cam(oblique_spec(), test_grid());
    const Vec3 want = normalized(cam.look_at() - cam.position());
    const Vec3 got = cam.pixel_direction(16, 12);  // the centre of a 33 x 25 image
    EXPECT_LT(norm(got - want), 1e-12);
    EXPECT_NEAR(norm(got), 1.0, 1e-14);
}

TEST(Camera, UpIsUpAndRightIsRight) {
    const CameraSpec spec = oblique_spec();
    const Camera cam(spec, test_grid());
    const Vec3 top = cam.pixel_direction(16, 0), bottom = cam.pixel_direction(16, 24);
    EXPECT_GT(dot(top, spec.up), dot(bottom, spec.up) + 0.1);  // row 0 looks higher
    const Vec3 world_right = cross(cam.forward(), spec.up);
    EXPECT_GT(dot(cam.pixel_direction(32, 12), world_right), 0.1);
    EXPECT_LT(dot(cam.pixel_direction(0, 12), world_right), -0.1);
    // A point above look_at (world up) projects into the upper half of the image: the ray
    // toward it is closer to the top-centre pixel's ray than to the bottom-centre one's.
    const Vec3 above = normalized(cam.look_at() + Vec3{0, 0, 1.0} - cam.position());
    EXPECT_LT(angle(above, top), angle(above, bottom));
}

TEST(Camera, FieldOfViewSpansTheImage) {
    const CameraSpec spec = oblique_spec();
    const Camera cam(spec, test_grid());
    const double vertical = angle(cam.direction(16.5, 0.0), cam.direction(16.5, 25.0));
    EXPECT_NEAR(vertical, spec.fov_deg * std::numbers::pi / 180, 1e-12);
    const double half_h = std::tan(0.5 * spec.fov_deg * std::numbers::pi / 180);
    const double horizontal = angle(cam.direction(0.0, 12.5), cam.direction(33.0, 12.5));
    EXPECT_NEAR(horizontal, 2 * std::atan(half_h * 33.0 / 25.0), 1e-12);
}

TEST(Camera, ProjectInvertsDirection) {
    const Camera cam(oblique_spec(), test_grid());
    for (double u : {0.0, 3.25, 16.5, 33.0})
        for (double v : {0.0, 7.5, 25.0}) {
            double pu, pv;
            ASSERT_TRUE(cam.project(cam.position() + cam.direction(u, v) * 7.0, pu, pv));
            EXPECT_NEAR(pu, u, 1e-9);
            EXPECT_NEAR(pv, v, 1e-9);
        }
    double pu, pv;
    EXPECT_FALSE(cam.project(cam.position() - cam.forward(), pu, pv));  // behind the camera
}

TEST(Camera, DegenerateViewsThrow) {
    CameraSpec same = oblique_spec();
    same.look_at = same.position;
    EXPECT_THROW(Camera(same, test_grid()), Error);
    CameraSpec parallel = oblique_spec();
    parallel.look_at = {0.9, -0.8, 0.1};  // straight down, up = +z
    EXPECT_THROW(Camera(parallel, test_grid()), Error);
}

// Whether some pixel's centre ray meets the domain in front of the camera, ray by ray.
bool some_pixel_sees(const Camera& cam, const Grid& grid) {
    for (int y = 0; y < cam.height(); ++y)
        for (int x = 0; x < cam.width(); ++x) {
            double t0, t1;
            if (intersect_box(cam.position(), cam.pixel_direction(x, y), grid.origin, grid.upper(), t0, t1) && t1 > 0)
                return true;
        }
    return false;
}

// The domain of the random views below: 10 x 5 x 20 m.
GridSpec views_grid() {
    GridSpec gs;
    gs.n = {20, 10, 40};
    gs.cell_size = 0.5;
    return gs;
}

// A random view around and inside views_grid()'s domain (domain units): position, view direction
// (its z scaled by view_z), up, field of view and image size.
CameraSpec random_view(std::mt19937& rng, double view_z = 1.0) {
    std::uniform_real_distribution<double> pos(-2.0, 3.0), dir(-1.0, 1.0), fov(5.0, 120.0);
    std::uniform_int_distribution<int> side(1, 120);
    CameraSpec c;
    c.position = {pos(rng), pos(rng), pos(rng)};
    c.look_at = c.position + Vec3{dir(rng), dir(rng), view_z * dir(rng)};
    c.up = {dir(rng), dir(rng), 1.0};
    c.fov_deg = fov(rng);
    c.width = side(rng);
    c.height = side(rng);
    return c;
}

// The scene-side check restates the pinhole model on the spec; on random views around and inside
// the domain it must give the answer of this camera's own rays, every pixel's centre traced.
TEST(Camera, SceneCheckThatTheCameraSeesTheDomainAgrees) {
    const GridSpec gs = views_grid();
    const Grid grid = make_grid(gs);
    std::mt19937 rng(12345);
    int seen = 0, unseen = 0;
    for (int trial = 0; trial < 600; ++trial) {
        CameraSpec c = random_view(rng);
        c.domain_units = trial % 2 == 0;
        if (!c.domain_units) {  // the same views in metres
            c.position = Vec3{c.position.x * 10, c.position.y * 5, c.position.z * 20};
            c.look_at = Vec3{c.look_at.x * 10, c.look_at.y * 5, c.look_at.z * 20};
        }
        const Camera cam(c, grid);
        const bool hit = some_pixel_sees(cam, grid);
        EXPECT_EQ(camera_sees_domain(c, gs), hit) << "trial " << trial;
        (hit ? seen : unseen) += 1;
    }
    EXPECT_GT(seen, 60);  // both answers are exercised
    EXPECT_GT(unseen, 60);
}

// A distant domain a few pixels wide is seen (a fixed 33 x 33 fan of rays over the field of view
// missed this one, 5 x 4 pixels of a 640 x 400 image: a QA case), and one that falls between the
// pixel centres of a tiny image is not.
TEST(Camera, SmallDomainsInTheImageAreSeenWhereAPixelCentreMeetsThem) {
    GridSpec gs;
    gs.n = {32, 32, 24};
    gs.cell_size = 75.0;
    const Grid grid = make_grid(gs);
    CameraSpec far;
    far.position = {0.5, -100.0, 0.5};
    far.look_at = {1.6, 0.5, 1.97};
    far.up = {0, 0, 1};
    far.fov_deg = 42.0;
    far.width = 640;
    far.height = 400;
    EXPECT_TRUE(some_pixel_sees(Camera(far, grid), grid));
    EXPECT_TRUE(camera_sees_domain(far, gs));
    // Centred, 0.2 pixels wide (2400 m at 240 km): on the centre of a 3 x 3 image, and between the
    // centres of 2 x 2.
    CameraSpec tiny = far;
    tiny.look_at = {0.5, 0.5, 0.5};
    tiny.fov_deg = 0.15 * 180.0 / std::numbers::pi;  // 0.05 rad per pixel of 3; the domain spans 0.01 rad
    tiny.width = tiny.height = 3;
    EXPECT_TRUE(some_pixel_sees(Camera(tiny, grid), grid));
    EXPECT_TRUE(camera_sees_domain(tiny, gs));
    tiny.width = tiny.height = 2;
    EXPECT_FALSE(some_pixel_sees(Camera(tiny, grid), grid));
    EXPECT_FALSE(camera_sees_domain(tiny, gs));
}

// With a ground background a view of the ground alone is a picture (a shadow beyond the
// domain): camera_sees_ground must say whether some pixel's centre ray goes down from above the
// ground, as this camera's own rays do, on random views.
TEST(Camera, SceneCheckThatTheCameraSeesTheGroundAgrees) {
    const GridSpec gs = views_grid();
    const Grid grid = make_grid(gs);
    std::mt19937 rng(777);
    int seen = 0, unseen = 0;
    for (int trial = 0; trial < 400; ++trial) {
        const CameraSpec c = random_view(rng, 0.3);  // flatter views: near the horizon
        const Camera cam(c, grid);
        bool down = false;
        for (int y = 0; y < cam.height() && !down; ++y)
            for (int x = 0; x < cam.width() && !down; ++x) down = cam.pixel_direction(x, y).z < 0.0;
        const bool want = cam.position().z > 0.0 && down;
        EXPECT_EQ(camera_sees_ground(c, gs), want) << "trial " << trial;
        (want ? seen : unseen) += 1;
    }
    EXPECT_GT(seen, 40);  // both answers are exercised
    EXPECT_GT(unseen, 40);
}

// A camera on a face of the domain sees it looking in and along the face, not looking out
// (every ray there leaves the closed box at t = 0).
TEST(Camera, ACameraOnAFaceSeesTheDomainOnlyLookingIn) {
    GridSpec gs;
    gs.n = {16, 12, 8};
    gs.cell_size = 1.0;
    const Grid grid = make_grid(gs);
    CameraSpec c;
    c.position = {0.0, 0.5, 0.5};
    c.up = {0, 0, 1};
    c.width = 24;
    c.height = 16;
    c.fov_deg = 40;
    for (double dx : {-1.0, 1.0, 1e-3}) {
        c.look_at = c.position + Vec3{dx, dx == 1e-3 ? 1.0 : 0.0, 0.0};
        EXPECT_EQ(camera_sees_domain(c, gs), some_pixel_sees(Camera(c, grid), grid)) << dx;
        EXPECT_EQ(camera_sees_domain(c, gs), dx > 0) << dx;
    }
}

// camera.up is checked in metres, where the camera is built: on a domain that is not a cube, an
// up parallel to the view in fractions of the extent is not in metres (and the reverse).
TEST(Camera, SceneChecksUpInMetres) {
    GridSpec gs;
    gs.n = {32, 32, 24};
    gs.cell_size = 75.0;
    Scene s;
    s.grid = gs;
    s.bands = {BandOptics{"gray", 1.0, 0.5, 0.0}};
    s.camera.domain_units = true;
    s.camera.position = {0, 0.5, 1.5};
    s.camera.look_at = {1, 0.5, 0.5};  // (1, 0, -1) in fractions, (0.8, 0, -0.6) in metres
    s.camera.up = {1, 0, -1};
    EXPECT_NO_THROW(s.validate());
    EXPECT_NO_THROW(Camera(s.camera, make_grid(gs)));
    s.camera.up = {4, 0, -3};
    EXPECT_THROW(s.validate(), Error);
    EXPECT_THROW(Camera(s.camera, make_grid(gs)), Error);
}

}  // namespace
}  // namespace nimbus
