// `nimbus run`: one run of the pipeline, with the run report printed at the end. A grid that
// would not fit in memory is refused before anything is allocated (src/cmd/memory.h).
#include <fmt/format.h>

#include "src/cmd/commands.h"
#include "src/cmd/memory.h"
#include "src/core/interrupt_cleanup.h"
#include "src/core/log.h"
#include "src/pipeline/pipeline.h"

namespace nimbus::cmd {
namespace {

void print_report(const RunResult& r) {
    const auto& rep = r.report;
    log::info("run report (wall seconds, max over ranks):");
    for (const auto& p : rep["phases"])
        log::info("  {:<28} {:9.3f}", p["name"].get<std::string>(), p["seconds"].get<double>());
    double peak = 0;
    for (double m : rep["peak_memory_bytes_per_rank"]) peak = std::max(peak, m);
    log::info("  {:<28} {:9.3f}", "total", rep["total_seconds"].get<double>());
    log::info("peak memory per rank: {:.1f} MiB (max over {} ranks)", peak / (1 << 20), rep["ranks"].get<int>());
    if (rep.contains("values")) {
        for (auto& [k, v] : rep["values"].items())
            if (v.is_object()) log::info("{}: {}", k, v.dump());
    }
    if (!r.hdf5_path.empty()) log::info("wrote {}", r.hdf5_path);
    if (!r.exr_path.empty()) log::info("wrote {} and {}", r.exr_path, r.png_path);
}

}  // namespace

void add_run_command(CLI::App& app) {
    auto opts = std::make_shared<RunOptions>();
    auto* run = app.add_subcommand("run", "Solve a scene and write fields (HDF5 + XDMF) and an image (EXR + PNG).\n"
                                          "Without SCENE: the built-in default cloud.");
    run->footer(kSceneHelpFooter);
    run->add_option("scene", opts->scene_path, "scene file (TOML)")->check(CLI::ExistingFile);
    run->add_option("--set", opts->overrides, "override a scene key, e.g. --set grid.n=[32,32,32] "
                                              "--set model.name=montecarlo (repeatable)")
        ->allow_extra_args(false);
    run->add_option("--out", opts->out_dir, "output folder (default: the scene's output.dir)")
        ->check([](const std::string& dir) { return dir.empty() ? std::string("the folder name is empty") : std::string(); });
    run->callback([opts] {
        MPI_Comm comm = MPI_COMM_WORLD;
        int rank = 0;
        MPI_Comm_rank(comm, &rank);
        interrupt_cleanup::install(rank == 0);  // an interrupted run removes its temporaries and new folders
        const Scene scene = load_run_scene(comm, *opts);
        check_memory_fits(comm, estimate_memory(scene, Decomposition(comm, scene.grid.n, scene.grid.process_grid,
                                                                     scene.grid.periodic)));
        print_report(run_pipeline(comm, scene));
    });
}

}  // namespace nimbus::cmd
