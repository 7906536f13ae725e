#include "solvers/lpm/lpm.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>

#include "solvers/lpm/angular.h"
#include "solvers/lpm/solve_band.h"
#include "src/core/error.h"
#include "src/core/log.h"
#include "src/core/progress.h"
#include "src/scene/emission.h"

namespace nimbus {
namespace {

class LightPropagationMaps final : public ScatteringModel {
public:
    explicit LightPropagationMaps(const LpmOptions& o) : opt_(o) { opt_.validate(); }
    std::string name() const override { return "lpm"; }
    nlohmann::json options() const override { return options_json(opt_); }

    // Per local cell: the 6k² coarse bins of unpropagated light U (8 bytes each) and ~186 bytes of
    // fluence, deposits, coefficients and halo planes; measured on the default cloud (slopes
    // between 48x48x32 and 96x96x64): 234 bytes at k = 1, 622 at k = 3 (p = 3; p does not matter).
    double memory_bytes(const Scene&, const Decomposition& d, int) const override {
        return (186.0 + 8.0 * 6 * opt_.k * opt_.k) * static_cast<double>(d.local().cells());
    }
    // Before the light pass: what the map sweeps need of the decomposition (and odd p's warning).
    void check_layout(const Decomposition& d) const override { check_decomposition(d); }
    void check(const Scene&, const Decomposition& d, const Medium&) const override {
        check_decomposition(d);
        if (opt_.p % 2 == 1 && (d.periodic(0) || d.periodic(1)) && d.rank() == 0)
            log::warn("model.lpm.p = {} is odd: the X and Y maps' horizontal rays never leave the periodic "
                      "layers and deposit all their light there (several times too much fluence on thin or "
                      "localized media); use an even p",
                      opt_.p);
    }
    void solve(const SolveContext& ctx, DiffuseSolution& out) override {
        const Decomposition& d = ctx.decomp;
        check_decomposition(d);
        check_collective(d.comm(), ctx.medium.rho.ghost() == 1 && ctx.medium.rho.owned() == d.local(),
                         "model lpm: density must cover the rank's box with one ghost layer");
        ScopedTimer timer(ctx.report, "lpm");
        const lpm::Angular ang(opt_.p, opt_.k);
        const int nb = ctx.medium.nbands();
        const std::vector<VolumeSource> sources = volume_sources(ctx.scene);  // [[sources]], q = power / 4π
        check_volume_sources(sources, ctx.medium.rho, d);
        Progress progress("lpm map sweeps", static_cast<double>(nb * opt_.iterations * 6), d.rank() == 0);
        out = DiffuseSolution{};
        nlohmann::json bands = nlohmann::json::array();
        for (int b = 0; b < nb; ++b) {
            lpm::BandResult r = lpm::solve_band(d, ctx.medium, ctx.light, b, opt_, ang, &progress, &ctx.report, sources);
            const double total = std::accumulate(r.sweep_seconds.begin(), r.sweep_seconds.end(), 0.0);
            const double mean = r.sweep_seconds.empty() ? 0.0 : total / static_cast<double>(r.sweep_seconds.size());
            bands.push_back({{"band", ctx.medium.bands[static_cast<size_t>(b)].name},
                             {"iterations", r.iterations},
                             {"max_U_relative", r.max_U},
                             {"seconds_per_map_sweep", mean},
                             {"wait_seconds", r.wait_seconds},
                             {"source_W", r.source},
                             {"escaped_W", r.escaped},
                             {"absorbed_W", r.absorbed},
                             {"unpropagated_W", r.remaining},
                             {"truncated_W", r.truncated},
                             {"unpropagated_W_per_iteration", r.remaining_history},
                             {"tail", opt_.tail},
                             {"tail_geometric_factor", r.tail_factor},
                             {"tail_diffusion_solver_iterations", r.tail_solver_iterations}});
            if (d.rank() == 0)
                log::info("lpm band {}: {} iterations, max U {:.3g} of the first-scatter maximum, {:.3g} s per map sweep, "
                          "unpropagated {:.3g} of the scattered power",
                          b, r.iterations, r.max_U.empty() ? 0.0 : r.max_U.back(), mean,
                          r.source > 0 ? r.remaining / r.source : 0.0);
            out.fluence.push_back(std::move(r.fluence));
            if (opt_.solution_bins == 4) out.flux.push_back(std::move(r.flux));
        }
        progress.finish();
        ctx.report.values()["lpm"] = {{"options", options()},
                                      {"map_directions", ang.map_bins()},
                                      {"coarse_bins", ang.coarse_bins()},
                                      {"bands", bands}};
    }

private:
    static void check_decomposition(const Decomposition& d) {
        if (!(d.is_slab_z() && !d.periodic(2)))
            throw Error(fmt::format("model lpm needs slabs along z (grid.process_grid = [1, 1, P]) and z not "
                                    "periodic; got {}", d.describe()));
    }

    LpmOptions opt_;
};

}  // namespace

std::unique_ptr<ScatteringModel> make_lpm_model(const LpmOptions& opt) {
    return std::make_unique<LightPropagationMaps>(opt);
}

}  // namespace nimbus
