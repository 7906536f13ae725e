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
