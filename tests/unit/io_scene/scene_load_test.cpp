// Scene files load, validate and round-trip: the built-in default and every example scene;
// scene_to_toml -> load_scene_string gives back every field of the Scene.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "io/scene/scene_toml.h"
#include "src/scene/emission.h"
#include "src/scene/medium.h"
#include "tests/support/mpi_test.h"
#include "tests/support/scratch_dir.h"

namespace nimbus {
namespace {

std::string scene_path(const std::string& name) { return std::string(NIMBUS_SOURCE_DIR) + "/scenes/" + name; }

// Every field of two scenes, exactly (bitwise for doubles), except `source`.
void expect_same_scene(const Scene& a, const Scene& b) {
    EXPECT_EQ(a.title, b.title);
    EXPECT_EQ(a.grid.n, b.grid.n);
    EXPECT_EQ(a.grid.cell_size, b.grid.cell_size);
    EXPECT_EQ(a.grid.unit, b.grid.unit);
    EXPECT_EQ(a.grid.unit_scale, b.grid.unit_scale);
    EXPECT_EQ(a.grid.h(), b.grid.h());
    EXPECT_EQ(a.grid.process_grid, b.grid.process_grid);
    EXPECT_EQ(a.grid.periodic, b.grid.periodic);
    const MediumSpec &ma = a.medium, &mb = b.medium;
    EXPECT_EQ(ma.kind, mb.kind);
    EXPECT_EQ(ma.density, mb.density);
    ASSERT_EQ(ma.ellipsoids.size(), mb.ellipsoids.size());
    for (size_t e = 0; e < ma.ellipsoids.size(); ++e) {
        EXPECT_EQ(ma.ellipsoids[e].center, mb.ellipsoids[e].center);
        EXPECT_EQ(ma.ellipsoids[e].radii, mb.ellipsoids[e].radii);
        EXPECT_EQ(ma.ellipsoids[e].density, mb.ellipsoids[e].density);
    }
    EXPECT_EQ(ma.noise_amplitude, mb.noise_amplitude);
    EXPECT_EQ(ma.noise_scale, mb.noise_scale);
    EXPECT_EQ(ma.noise_octaves, mb.noise_octaves);
    EXPECT_EQ(ma.seed, mb.seed);
    EXPECT_EQ(ma.box_lo, mb.box_lo);
    EXPECT_EQ(ma.box_hi, mb.box_hi);
    EXPECT_EQ(ma.sphere_center, mb.sphere_center);
    EXPECT_EQ(ma.sphere_radius, mb.sphere_radius);
    EXPECT_EQ(ma.file, mb.file);
    EXPECT_EQ(ma.dataset, mb.dataset);
    ASSERT_EQ(a.bands.size(), b.bands.size());
    for (size_t i = 0; i < a.bands.size(); ++i) {
        EXPECT_EQ(a.bands[i].name, b.bands[i].name);
        EXPECT_EQ(a.bands[i].sigma_t, b.bands[i].sigma_t);
        EXPECT_EQ(a.bands[i].albedo, b.bands[i].albedo);
        EXPECT_EQ(a.bands[i].g, b.bands[i].g);
    }
    EXPECT_EQ(a.sun.enabled, b.sun.enabled);
    EXPECT_EQ(a.sun.direction.x, b.sun.direction.x);
    EXPECT_EQ(a.sun.direction.y, b.sun.direction.y);
    EXPECT_EQ(a.sun.direction.z, b.sun.direction.z);
    EXPECT_EQ(a.sun.irradiance, b.sun.irradiance);
    EXPECT_EQ(a.sky.radiance, b.sky.radiance);
    EXPECT_EQ(a.sky.directions, b.sky.directions);
    EXPECT_EQ(a.light.method, b.light.method);
    ASSERT_EQ(a.sources.size(), b.sources.size());
    for (size_t i = 0; i < a.sources.size(); ++i) {
        EXPECT_EQ(a.sources[i].lo, b.sources[i].lo);
        EXPECT_EQ(a.sources[i].hi, b.sources[i].hi);
        EXPECT_EQ(a.sources[i].power, b.sources[i].power);
    }
    for (int d = 0; d < 3; ++d) {
        EXPECT_EQ(a.camera.position[d], b.camera.position[d]);
        EXPECT_EQ(a.camera.look_at[d], b.camera.look_at[d]);
        EXPECT_EQ(a.camera.up[d], b.camera.up[d]);
    }
    EXPECT_EQ(a.camera.fov_deg, b.camera.fov_deg);
    EXPECT_EQ(a.camera.width, b.camera.width);
    EXPECT_EQ(a.camera.height, b.camera.height);
    EXPECT_EQ(a.camera.domain_units, b.camera.domain_units);
    EXPECT_EQ(a.background.kind, b.background.kind);
    EXPECT_EQ(a.background.color, b.background.color);
    EXPECT_EQ(a.background.ground_albedo, b.background.ground_albedo);
    EXPECT_EQ(a.background.ground_color, b.background.ground_color);
    EXPECT_EQ(a.render.mode, b.render.mode);
    EXPECT_EQ(a.render.step, b.render.step);
    EXPECT_EQ(a.render.early_termination, b.render.early_termination);
    EXPECT_EQ(a.render.emission_color, b.render.emission_color);
    EXPECT_EQ(a.render.exposure, b.render.exposure);
    EXPECT_EQ(a.model.name, b.model.name);
    EXPECT_EQ(a.model.montecarlo, b.model.montecarlo);
    EXPECT_EQ(a.model.diffusion, b.model.diffusion);
    EXPECT_EQ(a.model.dom, b.model.dom);
    EXPECT_EQ(a.model.lpm, b.model.lpm);
    EXPECT_EQ(a.model.psf, b.model.psf);
    EXPECT_EQ(a.output.dir, b.output.dir);
    EXPECT_EQ(a.output.name, b.output.name);
    EXPECT_EQ(a.output.hdf5, b.output.hdf5);
    EXPECT_EQ(a.output.image, b.output.image);
}

// Writes s, reads it back, and checks every field and the re-serialized text; the same for the
// text with each key's meaning as a comment (docs/scene_reference.toml).
void expect_round_trip(const Scene& s) {
    const std::string text = scene_to_toml(s);
    const auto body = [](const std::string& t) { return t.substr(t.find('\n')); };  // minus the source comment
    for (const TomlComments comments : {TomlComments::none, TomlComments::meanings}) {
        SCOPED_TRACE(comments == TomlComments::none ? "without comments" : "with meanings");
        const Scene back = load_scene_string(scene_to_toml(s, comments), "<round trip>");
        expect_same_scene(s, back);
        EXPECT_EQ(body(scene_to_toml(back)), body(text));
    }
}

// Optical depth rho * sigma_t * h summed over the cells of one grid line through cell c.
double optical_depth(const Scene& s, int axis, Int3 c) {
    const ProceduralDensity rho(s.medium, s.grid.n);
    double tau = 0;
    for (c[axis] = 0; c[axis] < s.grid.n[axis]; ++c[axis])
        tau += rho(c[0], c[1], c[2]) * s.bands[0].sigma_t * s.grid.h();
    return tau;
}

TEST(SceneLoad, DefaultSceneHasTheFileValues) {
    const Scene s = default_scene();
    EXPECT_EQ(s.title, "default cumulus");
    EXPECT_EQ(s.grid.n, (Int3{96, 96, 64}));
    EXPECT_EQ(s.grid.h(), 25.0);
    EXPECT_EQ(s.medium.kind, MediumSpec::Kind::cumulus);
    EXPECT_EQ(s.medium.noise_octaves, 4);
    EXPECT_EQ(s.medium.seed, 7u);
    ASSERT_EQ(s.nbands(), 3);
    EXPECT_EQ(s.bands[1].name, "g");
    EXPECT_EQ(s.bands[2].albedo, 0.999);
    EXPECT_NEAR(norm(s.sun.direction), 1.0, 1e-15);  // normalized on load
    EXPECT_NEAR(s.sun.direction.x / s.sun.direction.z, 0.55 / -0.76, 1e-15);
    EXPECT_EQ(s.sun.irradiance, (std::vector<double>{1.0, 0.95, 0.85}));
    EXPECT_EQ(s.sky.radiance, (std::vector<double>{0.03, 0.05, 0.09}));
    EXPECT_EQ(s.camera.width, 640);
    EXPECT_EQ(s.camera.height, 400);
    EXPECT_EQ(s.camera.fov_deg, 42.0);
    EXPECT_TRUE(s.camera.domain_units);
    EXPECT_EQ(s.render.mode, RenderMode::scattering);
    EXPECT_EQ(s.render.exposure, 3.0);
    EXPECT_EQ(s.model.name, "montecarlo");
    EXPECT_EQ(s.model.montecarlo.photons, 1000000);
    EXPECT_EQ(s.output.name, "nimbus");
    EXPECT_NO_THROW(s.validate());
}

// The binary embeds scenes/default.toml at configure time (io/CMakeLists.txt): a stale copy,
// or loading from a string resolving anything differently from loading the file, fails here.
TEST(SceneLoad, BuiltInDefaultEqualsScenesDefaultToml) {
    const Scene file = load_scene_file(scene_path("default.toml"));
    EXPECT_EQ(file.source, scene_path("default.toml"));
    expect_same_scene(default_scene(), file);
}

class ExampleScene : public ::testing::TestWithParam<std::string> {};

TEST_P(ExampleScene, LoadsValidatesAndRoundTrips) {
    const Scene s = load_scene_file(scene_path(GetParam()));
    EXPECT_NO_THROW(s.validate());
    EXPECT_NO_THROW(s.model.montecarlo.validate());
    EXPECT_NO_THROW(s.model.diffusion.validate());
    EXPECT_LE(s.grid.n[0] * s.grid.n[1] * s.grid.n[2], 96 * 96 * 64);  // runs in seconds
    expect_round_trip(s);
}

INSTANTIATE_TEST_SUITE_P(Scenes, ExampleScene,
                         ::testing::Values("default.toml", "smoke.toml", "dense_cube.toml",
                                           "sphere_ground.toml", "slab.toml", "duct.toml"),
                         [](const auto& p) {
                             return p.param.substr(0, p.param.find('.'));
                         });

TEST(SceneLoad, SmokeIsAThinLowAlbedoPlume) {
    const Scene s = load_scene_file(scene_path("smoke.toml"));
    EXPECT_EQ(s.grid.n, (Int3{64, 64, 64}));
    EXPECT_EQ(s.grid.unit_scale, 0.01);
    EXPECT_EQ(s.medium.kind, MediumSpec::Kind::cumulus);
    EXPECT_EQ(s.medium.ellipsoids.size(), 4u);
    for (const BandOptics& b : s.bands) {
        EXPECT_NEAR(b.albedo, 0.6, 0.05);
        EXPECT_NEAR(b.g, 0.3, 0.05);
    }
    // Thin: the horizontal optical depth through the plume stays of order 1.
    double tau_max = 0;
    for (int k = 0; k < 64; k += 4)
        for (int j = 0; j < 64; j += 4) tau_max = std::max(tau_max, optical_depth(s, 0, {0, j, k}));
    EXPECT_GT(tau_max, 0.2);
    EXPECT_LT(tau_max, 2.0);
}

TEST(SceneLoad, DenseCubeHasOpticalThickness20) {
    const Scene s = load_scene_file(scene_path("dense_cube.toml"));
    EXPECT_EQ(s.grid.n, (Int3{48, 48, 48}));
    EXPECT_EQ(s.medium.kind, MediumSpec::Kind::box);
    EXPECT_EQ(s.bands[0].albedo, 0.99);
    EXPECT_EQ(s.bands[0].g, 0.85);
    for (int axis = 0; axis < 3; ++axis) EXPECT_NEAR(optical_depth(s, axis, {24, 24, 24}), 20.0, 1e-12);
    EXPECT_EQ(optical_depth(s, 0, {0, 5, 24}), 0.0);  // outside the cube
}

TEST(SceneLoad, SphereGroundHasAGroundBackground) {
    const Scene s = load_scene_file(scene_path("sphere_ground.toml"));
    EXPECT_EQ(s.medium.kind, MediumSpec::Kind::sphere);
    EXPECT_EQ(s.background.kind, BackgroundSpec::Kind::ground);
    EXPECT_EQ(s.background.ground_color.size(), 3u);
    // The sphere floats: the bottom layer of cells is empty.
    const ProceduralDensity rho(s.medium, s.grid.n);
    double bottom = 0;
    for (int j = 0; j < s.grid.n[1]; ++j)
        for (int i = 0; i < s.grid.n[0]; ++i) bottom += rho(i, j, 0) + rho(i, j, 1);
    EXPECT_EQ(bottom, 0.0);
    EXPECT_GT(optical_depth(s, 2, {24, 24, 0}), 1.0);
}

TEST(SceneLoad, SlabIsPeriodicWithOpticalThickness2) {
    const Scene s = load_scene_file(scene_path("slab.toml"));
    EXPECT_EQ(s.grid.periodic, (std::array<bool, 3>{true, true, false}));
    EXPECT_TRUE(s.sky.radiance.empty());
    for (int i : {0, 7, 15})
        for (int j : {0, 9, 15}) EXPECT_NEAR(optical_depth(s, 2, {i, j, 0}), 2.0, 1e-12);
}

TEST(SceneLoad, EveryFieldRoundTrips) {
    Scene s;  // every field away from its default
    s.title = "all \"fields\" \\ changed";
    s.grid.n = {7, 9, 11};
    s.grid.cell_size = 0.3;
    s.grid.unit = "custom";
    s.grid.unit_scale = 0.3048;
    s.grid.process_grid = {1, 0, 2};
    s.grid.periodic = {true, false, true};
    s.medium.kind = MediumSpec::Kind::sphere;
    s.medium.density = 0.1 + 0.2;  // not a short decimal
    s.medium.ellipsoids = {{{0.1, 0.2, 0.3}, {0.4, 0.5, 0.6}, 0.7}, {{0.9, 0.8, 0.7}, {0.1, 0.1, 0.2}, 1.0 / 3.0}};
    s.medium.noise_amplitude = 0.25;
    s.medium.noise_scale = 0.07;
    s.medium.noise_octaves = 6;
    s.medium.seed = 4000000000u;
    s.medium.box_lo = {0.1, 0.2, 0.3};
    s.medium.box_hi = {0.9, 0.8, 0.7};
    s.medium.sphere_center = {0.4, 0.45, 0.55};
    s.medium.sphere_radius = 0.123456789012345;
    s.medium.file = "/abs/path/density.h5";
    s.medium.dataset = "fields/rho";
    s.bands = {{"red", 1e-3, 0.5, -0.3}, {"blue", 2.5e4, 1.0, 0.0}};
    s.sun.enabled = false;
    s.light.method = s.light.method == LightSpec::Method::sweep ? LightSpec::Method::exact : LightSpec::Method::sweep;
    s.sun.direction = normalized(Vec3{1, 2, -3});
    s.sun.irradiance = {3.0, 4.0};
    s.sky.radiance = {0.5};
    s.sky.directions = 32;
    s.sources = {{{0.3, 0.6, 0.9}, {1.2, 2.7, 3.3}, {1.0 / 3.0, 2.0}}, {{0.0, 0.0, 0.0}, {2.1, 2.7, 3.3}, {5e-7}}};
    s.camera.position = {-10, 20, 30};
    s.camera.look_at = {1, 2, 3};
    s.camera.up = {0, 1, 0};
    s.camera.fov_deg = 12.5;
    s.camera.width = 33;
    s.camera.height = 17;
    s.camera.domain_units = false;
    s.background.kind = BackgroundSpec::Kind::ground;
    s.background.color = {0.1, 0.2};
    s.background.ground_albedo = 0.55;
    s.background.ground_color = {0.3, 0.4};
    s.render.mode = RenderMode::emission_absorption;
    s.render.step = 0.25;
    s.render.early_termination = 1e-6;
    s.render.emission_color = {0.9, 0.8};
    s.render.exposure = 7.5;
    s.model.name = "montecarlo";
    s.model.montecarlo = {123456789012, 60.0, 0.01, 9876543210, 16, 0.1, 2.5, true, 8};
    s.model.diffusion = {"petsc", 1e-10, 999, 5, 123.5, false, false, "levermore-pomraning", 7, 0.125,
                         "-diffusion_pc_type mg -diffusion_pc_mg_levels 2"};
    s.output = {"results/x", "run_7", false, false};
    ASSERT_NO_THROW(s.validate());
    expect_round_trip(s);
}

// The scene file's path goes into a comment of the stored scene: a newline or a byte that is not
// UTF-8 in it made the stored scene unreadable (a QA finding). Such bytes become '?'; valid
// UTF-8 stays.
TEST(SceneLoad, StoredSceneOfAnOddlyNamedFileRoundTrips) {
    Scene s = default_scene({});
    for (const std::string name : {"a\nb.toml", "bad\xff.toml", "tab\there\x7f.toml", "cut\xe2\x82.toml",
                                   "\xed\xa0\x80.toml", "\xe0\x80\x80.toml", "\xf0\x80\x80\x80.toml", "\xf4\x90\x80\x80.toml",
                                   "\xc0\xaf.toml", "caf\xc3\xa9 \xe2\x98\x81.toml"}) {
        s.source = name;
        expect_round_trip(s);
    }
    s.source = "caf\xc3\xa9 \xe2\x98\x81.toml";
    EXPECT_NE(scene_to_toml(s).find("source: caf\xc3\xa9 \xe2\x98\x81.toml)"), std::string::npos);
    s.source = "a\nb\xff.toml";
    EXPECT_NE(scene_to_toml(s).find("source: a?b?.toml)"), std::string::npos);
}

TEST(SceneLoad, SourcesCoverTheCellsWhoseCentresAreInside) {
    const std::string text = "[grid]\nn = [10, 8, 6]\ncell_size = 2\nunit = \"km\"\n[[optics]]\n"
                             "[model]\nname = \"dom\"\n"
                             "[[sources]]\nlo = [2, 0, 3]\nhi = [7, 16, 5.0001]\npower = 2.5\n"
                             "[[sources]]\nlo = [-5, -5, -5]\nhi = [2, 100, 100]\n";
    const Scene s = load_scene_string(text, "sources.toml");
    ASSERT_EQ(s.sources.size(), 2u);
    EXPECT_EQ(s.sources[0].power, std::vector<double>{2.5});
    EXPECT_EQ(s.sources[1].power, std::vector<double>{1.0});  // default
    // Centres at 1, 3, 5, ... km: x in [2, 7) -> cells 1..2 (3, 5); z in [3, 5.0001) -> cell 1
    // (centre 3) and 2 (centre 5); y covers the whole grid; a box past the domain is clipped.
    EXPECT_EQ(source_cells(s.sources[0], s.grid), (Box{{1, 0, 1}, {3, 8, 3}}));
    EXPECT_EQ(source_cells(s.sources[1], s.grid), (Box{{0, 0, 0}, {1, 8, 6}}));
    // Half-open: a face on a cell centre belongs to the box above it.
    SourceSpec edge{{1.0, 1.0, 1.0}, {3.0, 3.0, 3.0}, {1.0}};
    EXPECT_EQ(source_cells(edge, s.grid), (Box{{0, 0, 0}, {1, 1, 1}}));
    expect_round_trip(s);
}

TEST(SceneLoad, UnitsAndIntegersForFloats) {
    const std::string text = "[grid]\nn = [4, 4, 4]\ncell_size = 2\nunit = \"km\"\n"
                             "[[optics]]\nsigma_t = 1\nalbedo = 1\ng = 0\n"
                             "[camera]\nfov = 30\n[model.montecarlo]\nphotons = 1e6\n";
    const Scene s = load_scene_string(text, "units.toml");
    EXPECT_EQ(s.grid.unit_scale, 1000.0);
    EXPECT_EQ(s.grid.h(), 2000.0);
    EXPECT_EQ(s.bands[0].sigma_t, 1.0);
    EXPECT_EQ(s.bands[0].albedo, 1.0);
    EXPECT_EQ(s.camera.fov_deg, 30.0);
    EXPECT_EQ(s.model.montecarlo.photons, 1000000);
    for (const auto& [unit, scale] : std::vector<std::pair<std::string, double>>{{"m", 1}, {"cm", 0.01}, {"mm", 0.001}})
        EXPECT_EQ(load_scene_string("[grid]\nunit = \"" + unit + "\"\n[[optics]]\n", "u.toml").grid.unit_scale, scale);
    EXPECT_EQ(load_scene_string("[grid]\nunit = \"custom\"\nunit_scale = 0.3048\n[[optics]]\n", "u.toml").grid.h(), 0.3048);
}

// sun.direction is any finite non-zero vector: one whose square length under- or overflows a
// double (QA: [1e-200, 0, -1e-200] was refused as "not a non-zero finite vector") is normalized.
TEST(SceneLoad, SunDirectionOfAnyScale) {
    for (const char* w : {"[1e-200, 0, -1e-200]", "[1e200, 0, -1e200]", "[3, 0, -3]"}) {
        const Scene s = load_scene_string(std::string("[[optics]]\n[sun]\ndirection = ") + w + "\n", "sun.toml");
        EXPECT_NEAR(s.sun.direction.x, std::sqrt(0.5), 1e-15) << w;
        EXPECT_EQ(s.sun.direction.y, 0.0) << w;
        EXPECT_NEAR(s.sun.direction.z, -std::sqrt(0.5), 1e-15) << w;
    }
    EXPECT_THROW(load_scene_string("[[optics]]\n[sun]\ndirection = [0, 0, 0]\n", "sun.toml"), Error);
}

TEST(SceneLoad, DensityFileResolvesAgainstTheSceneFolder) {
    test::ScratchDir dir("resolve");
    if (test::world_rank() == 0) {
        std::ofstream(dir.file("d.raw")) << "x";
        std::filesystem::create_directories(dir.path() / "sub");
        std::ofstream(dir.file("sub/e.h5")) << "x";
        std::ofstream(dir.file("scene.toml"))
            << "[medium]\nkind = \"raw\"\nfile = \"d.raw\"\n[[optics]]\n";
    }
    MPI_Barrier(MPI_COMM_WORLD);
    const Scene s = load_scene_file(dir.file("scene.toml"));
    EXPECT_EQ(s.medium.kind, MediumSpec::Kind::raw);
    EXPECT_EQ(std::filesystem::path(s.medium.file), std::filesystem::canonical(dir.file("d.raw")));
    const Scene o = load_scene_file(dir.file("scene.toml"),
                                    {"medium.kind=hdf5", "medium.file=" + dir.file("sub/e.h5")});
    EXPECT_EQ(std::filesystem::path(o.medium.file), std::filesystem::canonical(dir.file("sub/e.h5")));
    expect_round_trip(s);  // an absolute path stays the same wherever the text is read
}

}  // namespace
}  // namespace nimbus
