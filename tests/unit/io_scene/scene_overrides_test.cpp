// "--set key=value" overrides: applied to the TOML tree before conversion, so they are
// checked like the file; every error about an override names it.
#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

#include "io/scene/scene_toml.h"
#include "src/core/box.h"
#include "src/core/error.h"

namespace nimbus {
namespace {

void expect_override_error(const std::vector<std::string>& overrides,
                           std::initializer_list<std::string> pieces) {
    try {
        default_scene(overrides);
        ADD_FAILURE() << "no error for " << overrides.back();
    } catch (const Error& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
        EXPECT_NE(msg.find("--set " + overrides.back()), std::string::npos) << "override not named: " << msg;
        for (const auto& p : pieces) EXPECT_NE(msg.find(p), std::string::npos) << "missing '" << p << "' in: " << msg;
    }
}

TEST(SceneOverrides, ValidOverridesChangeTheScene) {
    const Scene s = default_scene({"grid.n=[8, 16, 32]", "optics[1].albedo=0.5", "model.name=montecarlo",
                                   "model.montecarlo.photons=1000", "title=hello world", "sun.irradiance=2",
                                   "grid.periodic=[true,true,false]", "camera.units=world", "render.step = 1"});
    EXPECT_EQ(s.grid.n, (Int3{8, 16, 32}));
    EXPECT_EQ(s.bands[1].albedo, 0.5);
    EXPECT_EQ(s.bands[0].albedo, 0.999);
    EXPECT_EQ(s.model.name, "montecarlo");
    EXPECT_EQ(s.model.montecarlo.photons, 1000);  // [model.montecarlo] created by the override
    EXPECT_EQ(s.title, "hello world");           // not TOML: taken as a string
    EXPECT_EQ(s.sun.irradiance, std::vector<double>{2.0});
    EXPECT_EQ(s.grid.periodic, (std::array<bool, 3>{true, true, false}));
    EXPECT_FALSE(s.camera.domain_units);
    EXPECT_EQ(s.render.step, 1.0);
    EXPECT_EQ(s.grid.cell_size, 25.0);  // untouched keys keep the file's values
}

TEST(SceneOverrides, LaterOverridesWinAndCanRepairTheFile) {
    EXPECT_EQ(default_scene({"grid.n=[8,8,8]", "grid.n=[4,4,4]"}).grid.n, (Int3{4, 4, 4}));
    const std::string bad = "[[optics]]\nalbedo = 1.5\n";
    EXPECT_THROW(load_scene_string(bad, "x.toml"), Error);
    EXPECT_EQ(load_scene_string(bad, "x.toml", {"optics[0].albedo=0.25"}).bands[0].albedo, 0.25);
}

TEST(SceneOverrides, UnknownKeyNamesTheOverride) {
    expect_override_error({"medium.densty=2"}, {"<built-in default>: --set medium.densty=2", "medium.densty: unknown key",
                                                "did you mean 'density'?"});
    expect_override_error({"lights.sun=1"}, {"lights: unknown key"});
    expect_override_error({"model.montecarlo.photon=5"}, {"did you mean 'photons'?"});
}

TEST(SceneOverrides, BadValueNamesTheOverride) {
    expect_override_error({"optics[0].albedo=1.5"}, {"optics[0].albedo", "outside [0, 1]"});
    expect_override_error({"grid.n=big"}, {"grid.n must be an array of 3 integers", "found string \"big\""});
    expect_override_error({"grid.n=[0,4,4]"}, {"grid.nx = 0", "zero-size"});
    expect_override_error({"sun.enabled=yes"}, {"sun.enabled must be true or false"});
    expect_override_error({"render.mode=scatter"}, {"render.mode", "did you mean 'scattering'?"});
    // One entry of an array: the error is the --set's, not the line of the array in the file
    // (a QA finding: "default.toml:40: sky.radiance = -1 ...").
    expect_override_error({"sky.radiance[1]=-1"}, {"<built-in default>: --set sky.radiance[1]=-1: sky.radiance = -1"});
    expect_override_error({"grid.n[2]=8.5"}, {"<built-in default>: --set grid.n[2]=8.5: grid.n must be"});
}

TEST(SceneOverrides, MalformedOverrides) {
    expect_override_error({"grid.n"}, {"expected key=value"});
    expect_override_error({"optics[7].g=0.1"}, {"index 7 is out of range: optics has 3 entries"});
    expect_override_error({"grid.n.x=3"}, {"grid.n is not a table"});
    expect_override_error({"grid..n=3"}, {"malformed key"});
    expect_override_error({"=3"}, {"malformed key"});
}

}  // namespace
}  // namespace nimbus
