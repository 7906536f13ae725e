// `nimbus info SCENE`: what a run of this scene would face: grid, optical depths, memory per
// rank, which models suit it. Cheap: builds the density and sums columns, solves nothing.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>

#include "io/scene/density_import.h"
#include "solvers/registry.h"
#include "src/cmd/commands.h"
#include "src/core/log.h"
#include "src/physics/lights.h"
#include "src/pipeline/pipeline.h"
#include "src/scene/medium.h"

namespace nimbus::cmd {
namespace {

struct ColumnStats {
    double tau_max = 0, tau_mean = 0, cell_tau_max = 0, filled = 0;
    Box bbox{{1 << 30, 1 << 30, 1 << 30}, {-1, -1, -1}};
};

void info(const RunOptions& opts) {
    MPI_Comm comm = MPI_COMM_WORLD;
    const Scene s = load_run_scene(comm, opts);
    const Decomposition d(comm, s.grid.n, s.grid.process_grid, s.grid.periodic);
    Field<double> rho(d.local(), 1, 1, 0.0);
    if (s.medium.kind == MediumSpec::Kind::hdf5 || s.medium.kind == MediumSpec::Kind::raw)
        read_density(s.medium, d, rho);
    else
        fill_procedural_density(s.medium, d, rho);
    check_density(rho, d);

    // Column sums of rho along z (vertical optical depth per unit sigma_t), reduced over ranks.
    const Box& own = d.local();
    const int nx = s.grid.n[0], ny = s.grid.n[1];
    std::vector<double> col(static_cast<size_t>(nx) * ny, 0.0);
    double rho_max = 0, filled = 0;
    Box bb{{1 << 30, 1 << 30, 1 << 30}, {-1, -1, -1}};
    for_each_cell(own, [&](int i, int j, int k) {
        const double r = rho(i, j, k);
        col[static_cast<size_t>(j - own.lo[1]) * nx + (i - own.lo[0])] += r * s.grid.h();
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

    const auto lights = make_lights(s);
    const double local_cells = static_cast<double>(own.grown(1).cells());
    // Fields every run holds: rho, tau_rho per light, fluence per band (+ output copies), the
    // renderer's float view volume (16 bytes/cell) and the image fragments.
    const double fields = 1 + static_cast<double>(lights.size()) + 2.0 * s.nbands() + 2.0;
    double bytes = local_cells * 8 * fields + 40.0 * s.camera.width * s.camera.height;
    std::string what = "light pass, render";
    if (s.model.name == "montecarlo") {
        // The density is replicated on every rank with per-band sum/sum² tallies (batch means).
        bytes += static_cast<double>(d.global().cells()) * (24.0 + 28.0 * s.nbands());
        what += ", Monte Carlo (replicated grid)";
    } else if (s.model.name == "diffusion") {
        // hypre: 7-point matrix + ~6 vectors, x ~1.4 for the multigrid hierarchy; flux per band.
        bytes += local_cells * 8 * (13 * 1.4 + 3.0 * s.nbands());
        what += ", diffusion (hypre)";
    }

    log::info("scene: {} ({})", s.title, s.source);
    log::info("grid: {} x {} x {} = {} cells, cell {} m, domain {:.4g} x {:.4g} x {:.4g} m", s.grid.n[0],
              s.grid.n[1], s.grid.n[2], d.global().cells(), s.grid.h(), s.grid.n[0] * s.grid.h(),
              s.grid.n[1] * s.grid.h(), s.grid.n[2] * s.grid.h());
    log::info("decomposition: {}; largest rank box {} cells", d.describe(), own.cells());
    log::info("medium: {}; {:.1f}% of cells non-empty; bounding box of non-empty cells [{}, {}) x [{}, {}) x [{}, {})",
              to_string(s.medium.kind), 100.0 * filled / d.global().cells(), bb.lo[0], bb.hi[0], bb.lo[1],
              bb.hi[1], bb.lo[2], bb.hi[2]);
    for (const auto& b : s.bands) {
        log::info("band '{}': sigma_t {} /m, albedo {}, g {}; vertical optical depth max {:.3g}, mean over "
                  "cloudy columns {:.3g}; max cell optical depth kappa*h {:.3g}; transport depth (1 - a g) "
                  "times max {:.3g}",
                  b.name, b.sigma_t, b.albedo, b.g, b.sigma_t * cmax,
                  ccount > 0 ? b.sigma_t * csum / ccount : 0.0, b.sigma_t * rho_max * s.grid.h(),
                  b.sigma_t * cmax * (1 - b.albedo * b.g));
    }
    log::info("light terms: {} (sun {}, sky bins {})", lights.size(), s.sun.enabled ? "on" : "off",
              s.sky.radiance.empty() ? 0 : s.sky.directions);
    log::info("memory estimate per rank ({}): {:.1f} MiB", what, bytes / (1 << 20));
    const double tau = s.bands.empty() ? 0 : s.bands[0].sigma_t * cmax * (1 - s.bands[0].albedo * s.bands[0].g);
    std::string advice = tau < 0.3 ? "optically thin: 'single' is close to exact"
                       : tau < 3   ? "intermediate: multiple scattering matters; 'montecarlo' is the reference"
                                   : "optically thick: multiple scattering dominates; 'diffusion' suits the core, "
                                     "'montecarlo' is the reference";
    if (!s.sources.empty())
        advice = fmt::format("lit by {} volume source(s) ([[sources]]): only 'dom' and 'montecarlo' model them "
                             "('montecarlo' is the reference); optical depth: {}",
                             s.sources.size(), tau < 0.3 ? "thin" : tau < 3 ? "intermediate" : "thick");
    log::info("models in this build: {}; this scene is {}", fmt::format("{}", fmt::join(available_models(), ", ")), advice);
    log::info("model asked for: '{}'", s.model.name);
}

}  // namespace

void add_info_command(CLI::App& app) {
    auto opts = std::make_shared<RunOptions>();
    auto* cmd = app.add_subcommand("info", "Describe a scene: grid, optical depths, memory per rank, suitable models.");
    cmd->add_option("scene", opts->scene_path, "scene file (TOML); default: the built-in cloud")->check(CLI::ExistingFile);
    cmd->add_option("--set", opts->overrides, "override a scene key (repeatable)");
    cmd->callback([opts] { info(*opts); });
}

}  // namespace nimbus::cmd
