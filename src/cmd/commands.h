// Subcommands of the `nimbus` executable; each adds itself to the CLI11 app.
#pragma once

#include <CLI/CLI.hpp>

namespace nimbus::cmd {

void add_run_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_compare_command(CLI::App& app);

}  // namespace nimbus::cmd
