// Light terms: a uniform sky of radiance L puts irradiance π L on a horizontal plane.
#include <gtest/gtest.h>

#include <numbers>

#include "src/physics/lights.h"

namespace nimbus {
namespace {

TEST(Lights, SunFirstThenSkyBinsWithTheRightIrradiance) {
    Scene s;
    s.bands = {BandOptics{"r"}, BandOptics{"g"}};
    s.sun.direction = {0, 0, -2};
    s.sun.irradiance = {2.0, 3.0};
    s.sky.radiance = {0.5};
    s.sky.directions = 16;
    const auto lights = make_lights(s);
    ASSERT_EQ(lights.size(), 17u);
    EXPECT_EQ(lights[0].name, "sun");
    EXPECT_NEAR(lights[0].w.z, -1.0, 1e-15);
    EXPECT_EQ(lights[0].E0[1], 3.0);
    double horizontal = 0;
    for (size_t l = 1; l < lights.size(); ++l) {
        EXPECT_LT(lights[l].w.z, 0.0);  // sky light travels downward
        EXPECT_NEAR(norm(lights[l].w), 1.0, 1e-12);
        horizontal += lights[l].E0[0] * -lights[l].w.z;
    }
    EXPECT_NEAR(horizontal, std::numbers::pi * 0.5, 1e-12);
}

// A uniform sky must light a symmetric medium symmetrically: when 4 divides the bin count the
// bins are closed under the mirrors in x and y and the swap of x and y (a quarter turn with a
// mirror), so their net horizontal flux is 0. The spiral used before (and still for other
// counts) is not: with 8 bins its net horizontal flux was 10% of the vertical one, and a centred
// box was lit 11% off its mirror image.
TEST(Lights, SkyBinsAreSymmetricWhenFourDividesTheirCount) {
    for (int n : {4, 8, 16, 36}) {
        Scene s;
        s.sun.enabled = false;
        s.sky.radiance = {1.0};
        s.sky.directions = n;
        const auto lights = make_lights(s);
        ASSERT_EQ(lights.size(), static_cast<size_t>(n));
        auto has = [&](const Vec3& w) {
            for (const auto& l : lights)
                if (norm(l.w - w) < 1e-12) return true;
            return false;
        };
        Vec3 net{0, 0, 0};
        for (const auto& l : lights) {
            EXPECT_TRUE(has({-l.w.x, l.w.y, l.w.z})) << n << " bins: no mirror in x of " << l.name;
            EXPECT_TRUE(has({l.w.x, -l.w.y, l.w.z})) << n << " bins: no mirror in y of " << l.name;
            EXPECT_TRUE(has({l.w.y, l.w.x, l.w.z})) << n << " bins: no x-y swap of " << l.name;
            net = net + l.w * l.E0[0];
        }
        EXPECT_NEAR(net.x, 0.0, 1e-12) << n;
        EXPECT_NEAR(net.y, 0.0, 1e-12) << n;
        EXPECT_NEAR(-net.z, std::numbers::pi, 1e-12) << n;  // π L on a horizontal plane
    }
    // Other counts keep the spiral: still π L downward, not symmetric.
    Scene s;
    s.sun.enabled = false;
    s.sky.radiance = {1.0};
    s.sky.directions = 7;
    Vec3 net{0, 0, 0};
    for (const auto& l : make_lights(s)) net = net + l.w * l.E0[0];
    EXPECT_NEAR(-net.z, std::numbers::pi, 1e-12);
}

TEST(Lights, ADarkSkyGivesNoTerms) {
    Scene s;
    s.bands = {BandOptics{"r"}, BandOptics{"g"}};
    s.sky.directions = 8;
    s.sky.radiance = {0.0, 0.0};
    EXPECT_EQ(make_lights(s).size(), 1u);  // the sun alone
    s.sky.radiance = {0.0, 0.1};           // lit in one band: all its directions
    EXPECT_EQ(make_lights(s).size(), 9u);
}

}  // namespace
}  // namespace nimbus
