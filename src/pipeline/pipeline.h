// The pipeline of one run (DESIGN §2): scene -> decomposition -> medium -> light pass ->
// multiple-scattering model -> render -> HDF5 + images, with a run report. It does not know
// which model runs: it asks the registry for one and talks to it through ScatteringModel.
#pragma once

#include <mpi.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "src/model/model.h"
#include "src/render/image.h"
#include "src/scene/scene.h"

namespace nimbus {

struct RunOptions {
    std::string scene_path;              // empty: the built-in default scene
    std::vector<std::string> overrides;  // "key=value" applied to the scene
    std::string out_dir;                 // non-empty: overrides output.dir
};

struct RunResult {
    nlohmann::json report;               // the run report (same on every rank)
    std::string hdf5_path, exr_path, png_path;  // empty when not written
};

// Loads the scene of opts (collective: every rank gets the same scene or the same Error).
Scene load_run_scene(MPI_Comm comm, const RunOptions& opts);

// Collective. The output location's checks that need no folder made (path length, a file
// where the folder goes, a folder where an output file goes, an output that is the density
// file): run_pipeline makes them, and `nimbus info` calls them to refuse what a run would.
void check_output_location(MPI_Comm comm, const Scene& scene);

// Collective over comm. Throws Error (on every rank) on bad input, a failed solve or a failed
// write; a failed run leaves no output file under its final name and no temporary (all
// outputs are written under temporary names and renamed together at the end: OutputFiles).
RunResult run_pipeline(MPI_Comm comm, const RunOptions& opts);
RunResult run_pipeline(MPI_Comm comm, const Scene& scene);

// A model's fields must be finite before anything is rendered or written: a NaN or Inf means the
// model failed (an overflow, a diverged solve), and the run says so instead of writing it.
// Collective over d.comm(): throws the same Error on every rank, with the counts.
void check_finite_solution(const DiffuseSolution& diffuse, const Decomposition& d, const std::string& model);

// Likewise the image (held by rank 0 of comm, empty elsewhere): a NaN or Inf in any pixel
// (radiance, alpha or standard error) is an Error on every rank, with the count.
void check_finite_image(const Image& image, MPI_Comm comm);

}  // namespace nimbus
