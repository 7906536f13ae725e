// Subcommands of the `nimbus` executable; each adds itself to the CLI11 app.
#pragma once

#include <CLI/CLI.hpp>

namespace nimbus::cmd {

// The footer of `run --help` and `info --help`: the models a scene can name, and where every key is.
inline const char* kSceneHelpFooter =
    "Models (model.name): single (single scattering), diffusion (P1 on hypre multigrid), dom (discrete "
    "ordinates), lpm (light propagation maps), psf (the path-integral blur model), montecarlo (the reference). "
    "Every scene key, with its default and meaning: docs/scene_reference.toml. A relative output.dir is "
    "taken from the working directory, a relative medium.file from the scene file's folder.";

void add_run_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_compare_command(CLI::App& app);

}  // namespace nimbus::cmd
