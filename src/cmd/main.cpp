// nimbus: light transport in participating media on MPI ranks.
//   mpiexec -n 2 nimbus run [SCENE] [--set key=value ...] [--out DIR]
//   nimbus info SCENE
//   nimbus compare A.h5 B.h5 [--json]
#include <CLI/CLI.hpp>
#include <mpi.h>

#include <cstdio>

#include "src/cmd/commands.h"
#include "src/core/error.h"
#include "src/core/log.h"

int main(int argc, char** argv) {
    MPI_Init(&argc, &argv);
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);

    CLI::App app{"nimbus: light transport in clouds, smoke and fog on MPI ranks.\n"
                 "Run with mpiexec -n N nimbus ... ; rank 0 speaks."};
    app.set_version_flag("--version", "nimbus 0.1.0");
    std::string level = "info";
    bool all_ranks = false;
    app.add_option("--log-level", level, "trace | debug | info | warn | error | off")
        ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}))
        ->capture_default_str();
    app.add_flag("--log-all-ranks", all_ranks, "let every rank log, prefixed with its rank");
    app.require_subcommand(1);
    nimbus::cmd::add_run_command(app);
    nimbus::cmd::add_info_command(app);
    nimbus::cmd::add_compare_command(app);
    app.parse_complete_callback([&] { nimbus::log::init(rank, level, all_ranks); });

    int code = 0;
    try {
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            if (rank == 0) code = app.exit(e); else code = e.get_exit_code();
        }
    } catch (const nimbus::Error& e) {
        // Collective errors: every rank has the same message; rank 0 says it once.
        if (rank == 0) std::fprintf(stderr, "nimbus: error: %s\n", e.what());
        code = 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "nimbus: internal error on rank %d: %s\n", rank, e.what());
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    MPI_Finalize();
    return code;
}
