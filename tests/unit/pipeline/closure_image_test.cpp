// The ray caster's diffuse in-scatter rebuilt from a transport model's fluence and flux
// (src/physics/radiance_closure.h), end to end against the path tracer: a thin sphere of
// forward-scattering cloud (tau 3 across, albedo 0.999, g = 0.85) under an overhead sun, seen
// side-on and from above, where the diffuse light is a broad beam (|F| / fluence 0.62-0.82 in
// dom's solution). With the P1 shape, clamped to stay >= 0, dom's image was 2.17x the path
// tracer's side-on and 0.25x from above (relative error 1.12 and 0.79); the realizable closure
// brings both within 0.35 (the brightness within 0.75-1.0).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>

#include "io/output/image_io.h"
#include "io/scene/scene_toml.h"
#include "src/analysis/compare.h"
#include "src/pipeline/pipeline.h"
#include "tests/support/mpi_test.h"

namespace nimbus {
namespace {

namespace fs = std::filesystem;

const char* kSphere = R"(
title = "thin forward-scattering sphere"
[grid]
n = [16, 16, 16]
cell_size = 20.0
[medium]
kind = "sphere"
density = 1.0
sphere_center = [0.5, 0.5, 0.5]
sphere_radius = 0.4
[[optics]]
name = "gray"
sigma_t = 0.0117
albedo = 0.999
g = 0.85
[sun]
direction = [0.0, 0.0, -1.0]
irradiance = 1.0
[camera]
look_at = [0.5, 0.5, 0.5]
fov = 30.0
resolution = [16, 16]
units = "domain"
[background]
color = 0.0
[model]
name = "dom"
[model.montecarlo]
image = true
samples_per_pixel = 2048
photons = 20000
[output]
hdf5 = false
)";

// The image of `model` seen from `position` (domain units) with `up`; written under a scratch
// folder that is removed afterwards.
Image render(const std::string& model, const std::string& position, const std::string& up) {
    int pid = static_cast<int>(::getpid());
    MPI_Bcast(&pid, 1, MPI_INT, 0, MPI_COMM_WORLD);
    const fs::path dir = fs::temp_directory_path() / ("nimbus_closure_" + std::to_string(pid) + "_" + model);
    Scene s = load_scene_string(kSphere, "closure test",
                                {"model.name=\"" + model + "\"", "camera.position=" + position, "camera.up=" + up});
    s.output.dir = dir.string();
    const RunResult r = run_pipeline(MPI_COMM_WORLD, s);
    Image img;
    if (test::world_rank() == 0) img = read_exr(r.exr_path);
    MPI_Barrier(MPI_COMM_WORLD);
    if (test::world_rank() == 0) fs::remove_all(dir);
    return img;
}

void check_view(const std::string& position, const std::string& up, double lo, double hi, double max_error) {
    const Image dom = render("dom", position, up), mc = render("montecarlo", position, up);
    if (test::world_rank() != 0) return;
    const ImageError e = image_error(dom.rgba, mc.rgba);
    std::cout << "[ closure ] view from " << position << ": dom / path tracer brightness " << e.mean_ratio
              << ", relative error " << e.rel_error << "\n";
    EXPECT_GT(e.mean_ratio, lo);
    EXPECT_LT(e.mean_ratio, hi);
    EXPECT_LT(e.rel_error, max_error);
}

TEST(ClosureImage, ThinForwardScatteringSphereSideOn) { check_view("[0.5,-2.0,0.5]", "[0,0,1]", 0.9, 1.1, 0.25); }
TEST(ClosureImage, ThinForwardScatteringSphereFromAbove) { check_view("[0.5,0.45,2.5]", "[0,1,0]", 0.65, 1.1, 0.45); }

}  // namespace
}  // namespace nimbus
