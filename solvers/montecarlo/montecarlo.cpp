#include "solvers/montecarlo/montecarlo.h"

#include <fmt/format.h>

#include <cmath>
#include <string>

#include "solvers/montecarlo/forward.h"
#include "solvers/montecarlo/path_tracer.h"
#include "src/core/log.h"
#include "src/core/report.h"
#include "src/scene/emission.h"
#include "src/scene/optics_groups.h"

namespace nimbus {

namespace {

class MonteCarloModel final : public ScatteringModel {
public:
    explicit MonteCarloModel(const MonteCarloOptions& opt) : opt_(opt) { opt_.validate(); }

    std::string name() const override { return "montecarlo"; }

    nlohmann::json options() const override { return options_json(opt_); }

    void solve(const SolveContext& ctx, DiffuseSolution& out) override {
        mc::ForwardResult r;
        {
            ScopedTimer timer(ctx.report, "montecarlo/trace");
            const std::vector<VolumeSource> sources = volume_sources(ctx.scene);
            check_volume_sources(sources, ctx.medium.rho, ctx.decomp);
            mc::ForwardSettings settings;
            settings.tally_flux = opt_.flux;
            r = mc::trace_forward(ctx.decomp, ctx.medium, ctx.light.lights, sources, opt_, settings);
        }
        out.fluence = std::move(r.fluence);
        out.fluence_stderr = std::move(r.fluence_stderr);
        out.flux = std::move(r.flux);  // halo-exchanged, as the fluence; empty without opt_.flux

        const double cores = ctx.decomp.size();
        // Throughput of the tracing rounds; the fixed costs (setup, reduction) are reported apart.
        const double secs = std::max(r.trace_seconds, 1e-9);
        const double paths_per_s = static_cast<double>(r.photons) / secs / cores;
        const double coll_per_s = static_cast<double>(r.collisions) / secs / cores;
        const double coll_per_s_all = static_cast<double>(r.collisions) / std::max(r.seconds, 1e-9) / cores;
        nlohmann::json energy = nlohmann::json::array();
        for (size_t b = 0; b < r.counters.size(); ++b) {
            const mc::Counters& c = r.counters[b];
            double escaped = c[mc::escaped_direct];
            for (int f = 0; f < 6; ++f) escaped += c[mc::escaped_xlo + f];
            energy.push_back({{"band", ctx.medium.bands[b].name},
                              {"incident_W", c[mc::incident]},
                              {"emitted_W", c[mc::emitted]},
                              {"absorbed_W", c[mc::absorbed]},
                              {"escaped_W", escaped},
                              {"reflected_diffuse_W", c[mc::escaped_zhi]},
                              {"transmitted_diffuse_W", c[mc::escaped_zlo]},
                              {"transmitted_direct_W", c[mc::escaped_direct]}});
        }
        ctx.report.values()["montecarlo"] = {
            {"photons", r.photons},
            {"collisions", r.collisions},
            {"tallied_segments", r.segments},
            {"batches", r.batches},
            {"layout_batches", r.layout_batches},
            {"stop_reason", r.stop_reason},
            {"kernel", r.kernel},
            {"seconds", r.seconds},
            {"setup_seconds", r.setup_seconds},
            {"trace_seconds", r.trace_seconds},
            {"reduce_seconds", r.reduce_seconds},
            {"collisions_per_s_per_core_overall", coll_per_s_all},
            {"paths_per_s_per_core", paths_per_s},
            {"collisions_per_s_per_core", coll_per_s},
            {"rel_error_total_diffuse", r.rel_error},  // NaN (JSON null): nothing tallied
            {"replicated_memory_gb", r.replicated_gb},
            {"energy", energy}};
        log::info("montecarlo: {} photons, {} collisions in {:.2f} s ({} batches, stop: {}, {} kernel): setup "
                  "{:.3f} s, tracing {:.3f} s, reduction {:.3f} s",
                  r.photons, r.collisions, r.seconds, r.batches, r.stop_reason, r.kernel, r.setup_seconds,
                  r.trace_seconds, r.reduce_seconds);
        log::info("montecarlo: tracing {:.3g} paths/s/core, {:.3g} collisions/s/core ({:.3g} over the whole "
                  "solve; {:.1f} tallied cell segments per collision), relative error of the total diffuse power "
                  "{}, replicated grid {:.3f} GB per rank",
                  paths_per_s, coll_per_s, coll_per_s_all,
                  static_cast<double>(r.segments) / std::max<double>(1.0, static_cast<double>(r.collisions)),
                  std::isnan(r.rel_error) ? std::string("unknown (no diffuse power tallied)")
                                          : fmt::format("{:.2e}", r.rel_error),
                  r.replicated_gb);
        if (r.collisions == 0 && r.photons > 0)
            log::warn("montecarlo: none of the {} photons collided, so fluence_diffuse is 0 with an unknown error: "
                      "the medium is too thin for this photon count; raise model.montecarlo.photons",
                      r.photons);
    }

    bool renders_image() const override { return opt_.image; }
    // The limit trace_forward enforces, before the light pass.
    void check(const Scene& s, const Decomposition& d, const Medium&) const override {
        check_layout(d);
        mc::check_kernel(d.comm(), opt_);
        check_scene(s, d);
    }
    void check_scene(const Scene& s, const Decomposition& d) const override {
        mc::check_replicated_memory(d.global().hi, replicated_bytes(s, d, opt_), opt_);
    }
    double memory_bytes(const Scene& s, const Decomposition& d, int) const override { return replicated_bytes(s, d, opt_); }
    // A round traces one batch per rank (forward.h), so ranks beyond the batch count, or in the
    // last round of a count that is not a multiple of the ranks, wait: said before the run.
    void check_layout(const Decomposition& d) const override {
        const int ranks = d.size();
        const double busy = mc::busy_fraction(opt_.batches, ranks);
        if (busy >= mc::kBusyFractionToWarn) return;
        const int rounds = (opt_.batches + ranks - 1) / ranks;
        const int last = opt_.batches - (rounds - 1) * ranks;  // batches of the last round
        const int better = std::min(rounds * ranks, MonteCarloOptions::kMaxBatches);
        log::warn("model.montecarlo.batches = {} on {} ranks: a rank traces one batch per round, so {} {} "
                  "trace nothing{} and the ranks trace {:.0f}% of the time; {}",
                  opt_.batches, ranks, ranks - last, ranks - last == 1 ? "rank" : "ranks", rounds == 1 ? "" : fmt::format(" in the last of {} rounds", rounds),
                  100.0 * busy,
                  better > opt_.batches
                      ? fmt::format("batches = {} (a multiple of the ranks) traces the same photons with every "
                                    "rank busy", better)
                      : fmt::format("at most {} batches: the ranks beyond that stay idle",
                                    MonteCarloOptions::kMaxBatches));
    }

    Image render(const SolveContext& ctx) override {
        ScopedTimer timer(ctx.report, "montecarlo/render");
        return mc::path_trace_image(ctx, opt_);
    }

private:
    // The replicated arrays of trace_forward (forward.h), as the run counts them: the whole grid.
    static double replicated_bytes(const Scene& s, const Decomposition& d, const MonteCarloOptions& opt) {
        double source_cells = 0.0;
        for (const VolumeSource& src : volume_sources(s)) source_cells += static_cast<double>(src.cells.cells());
        return mc::replicated_bytes(static_cast<double>(d.global().cells()),
                                    static_cast<int>(group_by_optics(s.bands).size()), s.nbands(), false,
                                    source_cells, opt.flux);
    }
    MonteCarloOptions opt_;
};

}  // namespace

std::unique_ptr<ScatteringModel> make_montecarlo_model(const MonteCarloOptions& opt) {
    return std::make_unique<MonteCarloModel>(opt);
}

}  // namespace nimbus
