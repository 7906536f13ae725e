// `nimbus info SCENE`: what a run of this scene would face: grid, optical depths, memory per
// rank, which models suit it. Cheap: builds the density and sums columns, solves nothing. It
// makes the checks a run makes before computing (the scene, the model is in this build), and
// estimates the memory before it allocates anything: a grid that would not fit is reported as
// such, without building its density. The description is the command's output: rank 0 prints it
// to stdout (`nimbus info scene.toml > scene.txt`); warnings and errors go to the log (stderr).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <new>
#include <optional>
#include <utility>

#include "io/scene/density_import.h"
#include "solvers/light/sun_transmittance.h"
#include "solvers/registry.h"
#include "src/cmd/commands.h"
#include "src/cmd/memory.h"
#include "src/core/error.h"
#include "src/physics/lights.h"
#include "src/pipeline/pipeline.h"
#include "src/scene/emission.h"
#include "src/scene/medium.h"

namespace nimbus::cmd {
namespace {

// One line of the description, printed by rank 0.
template <class... Args>
void say(MPI_Comm comm, fmt::format_string<Args...> f, Args&&... a) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    if (rank != 0) return;
    std::fputs((fmt::format(f, std::forward<Args>(a)...) + "\n").c_str(), stdout);
    std::fflush(stdout);
}

// The decomposition `ranks` ranks would have, seen from the rank with the largest box (the one
// whose memory matters), planned without those ranks (info --ranks N).
Decomposition plan_for(const Scene& s, int ranks) {
    const Decomposition any = Decomposition::plan(s.grid.n, ranks, s.grid.process_grid, s.grid.periodic);
    int largest = 0;
    for (int p = 1; p < ranks; ++p)
        if (any.box_of(p).cells() > any.box_of(largest).cells()) largest = p;
    return Decomposition::plan(s.grid.n, ranks, s.grid.process_grid, s.grid.periodic, largest);
}

void info(const RunOptions& opts, int plan_ranks) {
    if (!opts.out_dir.empty()) throw Error("--out: info writes no files (--out is an option of nimbus run)");
    MPI_Comm comm = MPI_COMM_WORLD;
    int size = 1;
    MPI_Comm_size(comm, &size);
    if (plan_ranks > 0 && size > 1 && plan_ranks != size)
        throw Error(fmt::format("--ranks {} plans a run from one process, but {} ranks were started: run `nimbus "
                                "info --ranks {}` without mpiexec, or `mpiexec -n {} nimbus info`",
                                plan_ranks, size, plan_ranks, plan_ranks));
    const bool planning = plan_ranks > 0 && plan_ranks != size;
    const Scene s = load_run_scene(comm, opts);
    check_output_location(comm, s);  // as a run: info refuses what a run refuses before computing
    run_collective(comm, [&] { make_model(s.model); });  // as a run: is the model in this build?
    // Planning, the density is built on this one process (its process grid is 1x1x1) and the
    // ranks' layout and memory are the plan's.
    const Decomposition d(comm, s.grid.n, planning ? Int3{0, 0, 0} : s.grid.process_grid, s.grid.periodic);
    const std::optional<Decomposition> plan = planning ? std::optional(plan_for(s, plan_ranks)) : std::nullopt;
    const Decomposition& layout = plan ? *plan : d;
    const auto lights = make_lights(s);
    const MemoryEstimate mem = estimate_memory(s, layout);
    const auto say_grid = [&] {
        say(comm, "scene: {} ({})", s.title, s.source);
        say(comm, "grid: {} x {} x {} = {} cells, cell {} m, domain {:.4g} x {:.4g} x {:.4g} m", s.grid.n[0],
                  s.grid.n[1], s.grid.n[2], d.global().cells(), s.grid.h(), s.grid.n[0] * s.grid.h(),
                  s.grid.n[1] * s.grid.h(), s.grid.n[2] * s.grid.h());
        say(comm, "decomposition{}: {}; largest rank box {} cells", plan ? " (planned with --ranks)" : "",
            layout.describe(), plan ? plan->local().cells() : [&] {
                long long largest = 0;
                for (int p = 0; p < d.size(); ++p)
                    largest = std::max(largest, static_cast<long long>(d.box_of(p).cells()));
                return largest;
            }());
    };
    // The rank with the largest box needs the most: its figure is the one to plan with.
    double most = mem.bytes;
    MPI_Allreduce(MPI_IN_PLACE, &most, 1, MPI_DOUBLE, MPI_MAX, comm);
    const auto say_memory = [&] {
        say(comm, "memory estimate per rank ({}): {:.1f} MiB{}", mem.what, most / (1 << 20),
            plan ? fmt::format("; {:.2f} GiB for the {} ranks together", mem.bytes * plan_ranks / (1 << 30),
                               plan_ranks)
                 : std::string());
    };
    // Planned ranks run elsewhere (other nodes): this node's memory says nothing about them. But
    // the description of the medium builds the whole density here; a grid planned for many
    // ranks may not fit on this one: the plan is then the whole description.
    try {
        if (!plan) check_memory_fits(comm, mem);
    } catch (const Error&) {
        say_grid();
        say_memory();
        throw;
    }
    if (plan) {
        try {
            check_memory_fits(comm, estimate_memory(s, d));
        } catch (const Error&) {
            // What a run on the plan's ranks refuses without the density is refused here too
            // (Monte Carlo's replicated grid beyond max_replicated_memory_gb; a QA finding: only
            // grids small enough to describe were checked).
            const auto model = make_model(s.model);
            model->check_layout(*plan);
            model->check_scene(s, *plan);
            say_grid();
            say_memory();
            say(comm, "medium: not described: its optical depths need the whole density on this one process, "
                      "which does not fit here (run `mpiexec -n {} nimbus info` on the machine for the run)",
                plan_ranks);
            return;
        }
    }
    // The density as a run builds it (allocated collectively: no rank is left waiting when
    // another runs out of memory), checked like a run's.
    const Medium m = load_medium(s, d);
    const Field<double>& rho = m.rho;

    // Column sums of rho along z (vertical optical depth per unit sigma_t), reduced over ranks.
    const Box& own = d.local();
    const int nx = s.grid.n[0], ny = s.grid.n[1];
    std::vector<double> col(static_cast<size_t>(nx) * ny, 0.0);
    double rho_max = 0, filled = 0;
    Box bb{{1 << 30, 1 << 30, 1 << 30}, {-1, -1, -1}};
    for_each_cell(own, [&](int i, int j, int k) {
        const double r = rho(i, j, k);
        col[static_cast<size_t>(j) * nx + i] += r * s.grid.h();  // global column: x/y may be split too
        rho_max = std::max(rho_max, r);
        if (r > 0) {
            filled += 1;
            for (int a = 0; a < 3; ++a) {
                const int v = a == 0 ? i : (a == 1 ? j : k);
                bb.lo[a] = std::min(bb.lo[a], v);
                bb.hi[a] = std::max(bb.hi[a], v + 1);
            }
        }
    });
    std::vector<double> colsum(col.size());
    MPI_Allreduce(col.data(), colsum.data(), static_cast<int>(col.size()), MPI_DOUBLE, MPI_SUM, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &rho_max, 1, MPI_DOUBLE, MPI_MAX, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &filled, 1, MPI_DOUBLE, MPI_SUM, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, bb.lo.data(), 3, MPI_INT, MPI_MIN, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, bb.hi.data(), 3, MPI_INT, MPI_MAX, d.comm());
    double cmax = 0, csum = 0, ccount = 0;
    for (double c : colsum) { cmax = std::max(cmax, c); if (c > 0) { csum += c; ccount += 1; } }

    // The checks a run makes once the density exists, before its light pass (pipeline.cpp): a
    // scene a run would refuse gets the run's one-line error and no description.
    // Planned: the checks of the decomposition alone are made on the plan, as on its N ranks.
    const auto model = make_model(s.model);
    check_light_method(layout, s.light.method);
    if (plan) model->check_layout(*plan);
    check_volume_sources(volume_sources(s), m.rho, d);
    model->check(s, d, m);
    check_lights_leave(d, make_lights(s));  // after the model's own, more specific refusals

    say_grid();
    say(comm, "medium: {}; {:.1f}% of cells non-empty; {}", to_string(s.medium.kind),
              100.0 * filled / static_cast<double>(d.global().cells()),
              filled > 0 ? fmt::format("bounding box of non-empty cells [{}, {}) x [{}, {}) x [{}, {})", bb.lo[0],
                                       bb.hi[0], bb.lo[1], bb.hi[1], bb.lo[2], bb.hi[2])
                         : std::string("no non-empty cells"));
    for (const auto& b : s.bands) {
        say(comm, "band '{}': sigma_t {} /m, albedo {}, g {}; vertical optical depth max {:.3g}, mean over "
                  "cloudy columns {:.3g}; max cell optical depth kappa*h {:.3g}; transport depth (1 - a g) "
                  "times max {:.3g}",
                  b.name, b.sigma_t, b.albedo, b.g, b.sigma_t * cmax,
                  ccount > 0 ? b.sigma_t * csum / ccount : 0.0, b.sigma_t * rho_max * s.grid.h(),
                  b.sigma_t * cmax * (1 - b.albedo * b.g));
    }
    const bool has_sun = !lights.empty() && lights[0].name == "sun";
    say(comm, "light terms: {} (sun {}, sky bins {})", lights.size(), has_sun ? "on" : "off",
        lights.size() - (has_sun ? 1 : 0));
    say_memory();
    const double tau = s.bands.empty() ? 0 : s.bands[0].sigma_t * cmax * (1 - s.bands[0].albedo * s.bands[0].g);
    std::string advice = tau < 0.3 ? "optically thin: 'single' is close to exact"
                       : tau < 3   ? "intermediate: multiple scattering matters; 'montecarlo' is the reference"
                                   : "optically thick: multiple scattering dominates; 'diffusion' suits the core, "
                                     "'montecarlo' is the reference";
    if (filled == 0)
        advice = "empty (density 0 everywhere): nothing scatters, every model gives zero diffuse light and the "
                 "image shows the background (check medium.density and medium.kind)";
    else if (!s.sources.empty())
        advice = fmt::format("lit by {} volume source(s) ([[sources]]): 'dom', 'diffusion', 'lpm' and "
                             "'montecarlo' model them ('montecarlo' is the reference; 'diffusion' has no "
                             "transport across empty cells); optical depth: {}",
                             s.sources.size(), tau < 0.3 ? "thin" : tau < 3 ? "intermediate" : "thick");
    // Thick CELLS are a matter of resolution, whatever the scene's depth (the diffusion model warns
    // from the same 4 optical depths per cell: solvers/diffusion/README.md, "Optically thick cells").
    double sigma_max = 0.0;
    for (const auto& b : s.bands) sigma_max = std::max(sigma_max, b.sigma_t);
    const double cell_tau = sigma_max * rho_max * s.grid.h();
    if (filled > 0 && cell_tau > 4.0)
        advice += fmt::format("; cells up to {:.3g} optical depths thick: lpm's P1 tail comes out too bright there "
                              "(1.7x Monte Carlo at 5 per cell, 5.4x at 20); 'diffusion' (0.96-1.08x on a box at 5-20 "
                              "per cell) and 'dom' (0.80-1.16x, but 1.2-1.6x with absorption, albedo 0.5-0.9) do not resolve the field; refine "
                              "the grid to about 1 per cell ('dom' with its step scheme to well under 1 per cell of "
                              "transport depth where the albedo is near 1: its run says how much it over-diffuses)",
                              cell_tau);
    say(comm, "models in this build: {}; this scene is {}", fmt::format("{}", fmt::join(available_models(), ", ")), advice);
    say(comm, "model asked for: '{}'", s.model.name);
    if (plan)
        say(comm, "planned for {} ranks from one process: the process grid was checked as that run checks "
                  "it; what needs the ranks themselves (the memory each machine has) is checked by "
                  "`mpiexec -n {} nimbus info` there", plan_ranks, plan_ranks);
}

}  // namespace

void add_info_command(CLI::App& app) {
    auto opts = std::make_shared<RunOptions>();
    auto* cmd = app.add_subcommand("info", "Describe a scene: grid, optical depths, memory per rank, suitable models.");
    cmd->footer(kSceneHelpFooter);
    cmd->add_option("scene", opts->scene_path, "scene file (TOML); default: the built-in cloud")->check(CLI::ExistingFile);
    cmd->add_option("--set", opts->overrides, "override a scene key, e.g. --set grid.n=[32,32,32] (repeatable)")
        ->allow_extra_args(false);
    // `run`'s --out given to info: said so by info(), rather than its folder taken for the scene.
    cmd->add_option("--out", opts->out_dir, "not an option of info")->group("");
    auto ranks = std::make_shared<int>(0);
    cmd->add_option("--ranks", *ranks,
                    "plan a run on N ranks from one process (no mpiexec): the decomposition and the memory "
                    "per rank of an N-rank run")
        ->check(CLI::Range(1, 1 << 24));
    cmd->callback([opts, ranks] { info(*opts, *ranks); });
}

}  // namespace nimbus::cmd
