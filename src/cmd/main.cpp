// nimbus: light transport in participating media on MPI ranks.
//   mpiexec -n 2 nimbus run [SCENE] [--set key=value ...] [--out DIR]
//   nimbus info [SCENE] [--set key=value ...]
//   nimbus compare A.h5 B.h5 [--json]
// Exit status: 0 on success (and for --help, --version), 1 on a usage error or bad input (one
// "nimbus: error:" line from rank 0) and when memory runs out (on one rank: MPI_Abort with 1),
// 2 when a rank fails on its own (internal error).
#include <CLI/CLI.hpp>
#include <mpi.h>

#include <cstdio>
#include <new>
#include <string>

#include "src/cmd/commands.h"
#include "src/core/error.h"
#include "src/core/log.h"
#include "src/core/mpi_init.h"

namespace {

// One line for a CLI11 parse error: what is wrong, naming the argument, and where help is.
std::string usage_message(const CLI::App& app, const CLI::ParseError& e) {
    const auto subs = app.get_subcommands();
    std::string what = e.what();
    const bool global_option = what.rfind("--log-", 0) == 0;  // --log-level, --log-all-ranks
    const std::string help = subs.empty() || global_option ? "nimbus --help"
                                                            : "nimbus " + subs.front()->get_name() + " --help";
    if (subs.empty() && e.get_name() == "RequiredError") {
        // No subcommand matched: name what was typed instead of "A subcommand is required".
        std::string typed, option;
        for (const std::string& a : app.remaining()) {
            if (!a.empty() && a[0] == '-') {
                if (option.empty()) option = a;
                continue;
            }
            typed = a;
            break;
        }
        what = !typed.empty()  ? "unknown command '" + typed + "'; commands: run, info, compare"
               : !option.empty() ? "unknown option '" + option + "' and no command; commands: run, info, compare"
                                 : "a command is required: run, info or compare";
    }
    for (char& c : what)
        if (c == '\n') c = ' ';
    return what + " (see " + help + ")";
}

}  // namespace

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);

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
    // The global options may also follow the subcommand (`nimbus run --log-level debug`): the
    // subcommands, which inherit this setting, pass the options they do not know to the app.
    app.fallthrough();
    nimbus::cmd::add_run_command(app);
    nimbus::cmd::add_info_command(app);
    nimbus::cmd::add_compare_command(app);
    // A subcommand's --help lists only its own options: name the global ones there too.
    for (CLI::App* sub : app.get_subcommands({})) {
        const std::string footer = sub->get_footer();
        sub->footer((footer.empty() ? "" : footer + "\n\n") +
                    "Global options, before or after the command: --log-level trace|debug|info|warn|error|off "
                    "(default info; debug adds the solvers' per-iteration lines), --log-all-ranks (every rank "
                    "logs, prefixed with its rank); see nimbus --help.");
    }
    app.parse_complete_callback([&] { nimbus::log::init(rank, level, all_ranks); });

    int code = 0;
    try {
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
                if (rank == 0) app.exit(e);  // --help, --version
            } else {
                if (rank == 0) std::fprintf(stderr, "nimbus: error: %s\n", usage_message(app, e).c_str());
                code = 1;
            }
        }
    } catch (const nimbus::Error& e) {
        // Collective errors: every rank has the same message; rank 0 says it once.
        if (rank == 0) std::fprintf(stderr, "nimbus: error: %s\n", e.what());
        code = 1;
    } catch (const std::bad_alloc&) {
        // Not collective: the other ranks may be waiting for this one, hence the abort.
        std::fprintf(stderr,
                     "nimbus: error: not enough memory on rank %d; use more ranks (on more nodes) or a smaller "
                     "grid; `nimbus info` estimates the memory per rank\n",
                     rank);
        if (size > 1) MPI_Abort(MPI_COMM_WORLD, 1);
        code = 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "nimbus: internal error on rank %d: %s\n", rank, e.what());
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    MPI_Finalize();
    return code;
}
