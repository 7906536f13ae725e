#include "solvers/lpm/lpm.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <numeric>

#include "solvers/lpm/angular.h"
#include "solvers/lpm/solve_band.h"
#include "src/core/error.h"
#include "src/core/log.h"
#include "src/core/progress.h"
#include "src/physics/band_groups.h"
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
    // between 48x48x32 and 96x96x64): 234 bytes at k = 1, 622 at k = 3 (p = 3). Per map plane, a
    // ray per direction (p² doubles per cell of the plane, phi), and on the lateral maps two ray
    // slot buffers of R² rays per cell and direction (R = refinement): 8 p² (nx ny + 2 R² max(nx,
    // ny) nz) bytes of the rank's box. (Measured, 2 ranks: 96x96x8 at p = 24 peaks 42 MiB above
    // p = 6, the term gives 43; 48x48x32 at R = 4 5.7 MiB above R = 1, the term 6.3; 32x32x24 at
    // p = 40 15 MiB above the per-cell part, the term 22. A QA finding: p and R were left out.)
    double memory_bytes(const Scene&, const Decomposition& d, int nlights) const override {
        const Box& b = d.local();
        const double p2 = static_cast<double>(opt_.p) * opt_.p, r2 = static_cast<double>(opt_.refinement) * opt_.refinement;
        const double planes = static_cast<double>(b.size(0)) * b.size(1) +
                              2.0 * r2 * std::max(b.size(0), b.size(1)) * static_cast<double>(b.size(2));
        // The source pass holds the first-scatter means it keeps (FirstScatterMeans), one per light.
        const double kept = 8.0 * std::min(nlights, FirstScatterMeans::kMaxKeptLights);
        // The maps' rays and their sweep buffers: 1.3 x 8 p² per plane cell, from peaks measured
        // at p 64 and 128 (16³ sphere, 2 ranks: 5257 B per p² against 4096 counted; the estimate
        // was 18-21% low at p 100-200, a QA finding). A periodic x or y sweep also keeps the last
        // K = p / gcd(p, n R) maps of the lateral plane it sweeps (map_sweep.cpp's filling test).
        const double lateral = r2 * std::max(b.size(0), b.size(1)) * static_cast<double>(b.size(2));
        long ring = 0;
        for (int a = 0; a < 2; ++a)
            if (d.periodic(a))
                ring = std::max<long>(ring, opt_.p / std::gcd(opt_.p, d.global().size(a) * opt_.refinement));
        return (186.0 + 8.0 * 6 * opt_.k * opt_.k + kept) * static_cast<double>(b.cells()) +
               8.0 * p2 * (1.3 * planes + static_cast<double>(ring) * lateral);
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
        const Medium& m = ctx.medium;
        const int nb = m.nbands();
        const std::vector<VolumeSource> sources = volume_sources(ctx.scene);  // [[sources]], q = power / 4π
        check_volume_sources(sources, m.rho, d);
        // Bands with equal optics share their map sweeps, one solve per colour of the source
        // terms (src/physics/band_groups.h): the maps are linear in the source, so band b is a sum
        // of scaled solves (the default cloud: the sun and the sky, 2 solves for 3 bands). Only the
        // geometric tail, a ratio of the last two iterations, is not linear: it solves per band.
        // Two solves also differ from one where the epsilon stop ends them at different
        // iterations (each is then within its own epsilon) or the diffusion tail clamps a negative
        // U (a few lit surface cells at most; tail "diffusion" only: DSA's solves are not clamped).
        const std::vector<BandGroup> groups =
            group_bands(m.bands, term_strengths(ctx.light.lights, sources, nb), opt_.tail != "geometric");
        int nsolves = 0;
        for (const BandGroup& g : groups) nsolves += static_cast<int>(g.rhs_weights.size());
        Progress progress("lpm map sweeps", static_cast<double>(nsolves * opt_.iterations * 6), d.rank() == 0);
        out = DiffuseSolution{};
        for (int b = 0; b < nb; ++b) {
            out.fluence.emplace_back(d.local(), 1, 1, 0.0);
            if (opt_.solution_bins == 4) out.flux.emplace_back(d.local(), 1, 3, 0.0);
        }
        nlohmann::json solves = nlohmann::json::array();
        for (const BandGroup& group : groups)
            for (size_t rhs = 0; rhs < group.rhs_weights.size(); ++rhs) {
                const std::vector<double>& weight = group.rhs_weights[rhs];
                const std::vector<std::string> band_names = rhs_band_names(group, rhs, m.bands);
                const double offset = static_cast<double>(solves.size()) * opt_.iterations * 6;
                lpm::BandResult r = lpm::solve_sources(d, m, ctx.light, group.optics, weight, opt_, ang, &progress,
                                                       offset, &ctx.report, sources);
                r.first_scatter.report(fmt::format("{}", fmt::join(band_names, ", ")), ctx.report, d.rank() == 0);
                const double total = std::accumulate(r.sweep_seconds.begin(), r.sweep_seconds.end(), 0.0);
                const double mean = r.sweep_seconds.empty() ? 0.0 : total / static_cast<double>(r.sweep_seconds.size());
                const std::vector<std::string> terms = term_names(weight, ctx.light.lights, sources.size());
                solves.push_back({{"bands", band_names},
                                  {"terms", terms},
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
                                  {"tail", r.dsa_diverged_max_U.empty() ? opt_.tail : std::string("diffusion")},
                                  {"dsa_diverged_max_U_relative", r.dsa_diverged_max_U},
                                  {"tail_geometric_factor", r.tail_factor},
                                  {"tail_diffusion_solver_iterations", r.tail_solver_iterations},
                                  {"dsa_corrections", r.dsa_corrections},
                                  {"dsa_solver_iterations", r.dsa_solver_iterations}});
                if (d.rank() == 0 && !r.dsa_diverged_max_U.empty())
                    log::warn("lpm {} {}: DSA diverged (max |U| {:.3g} of the first-scatter maximum after round {}, "
                              "{:.3g} after round {}: its P1 corrections are not consistent with the maps on "
                              "optically thick cells at this albedo); solved again with model.lpm.tail = "
                              "\"diffusion\", set it to skip the failed start",
                              band_names.size() == 1 ? "band" : "bands", fmt::join(band_names, ", "),
                              r.dsa_diverged_max_U.end()[-2], r.dsa_diverged_max_U.size() - 1,
                              r.dsa_diverged_max_U.back(), r.dsa_diverged_max_U.size());
                if (d.rank() == 0)
                    log::info("lpm {} {} ({}): {} iterations, max U {:.3g} of the first-scatter maximum, {:.3g} s per "
                              "map sweep, unpropagated {:.3g} of the scattered power",
                              band_names.size() == 1 ? "band" : "bands", fmt::join(band_names, ", "),
                              fmt::join(terms, ", "), r.iterations,
                              r.max_U.empty() ? 0.0 : r.max_U.back(), mean, r.source > 0 ? r.remaining / r.source : 0.0);
                // Each band that uses this solve adds it at its scale (owned cells and ghosts:
                // both results are halo-exchanged).
                for_each_use(group, rhs, [&](int band, double scale) {
                    const auto b = static_cast<size_t>(band);
                    Field<double>& fl = out.fluence[b];
                    for (size_t q = 0; q < fl.size(); ++q) fl.data()[q] += scale * r.fluence.data()[q];
                    if (opt_.solution_bins == 4) {
                        Field<double>& fx = out.flux[b];
                        for (size_t q = 0; q < fx.size(); ++q) fx.data()[q] += scale * r.flux.data()[q];
                    }
                });
            }
        progress.finish();
        ctx.report.values()["lpm"] = {{"options", options()},
                                      {"map_directions", ang.map_bins()},
                                      {"coarse_bins", ang.coarse_bins()},
                                      {"solves", solves}};
        // The exact fluence is never negative; DSA's corrections carry the current (3 g F·ω) and
        // are not clamped, so at large |g| they can leave a few percent below zero next to the
        // medium (QA: -3.3% of the peak at g = 0.99; the plain tail clamps).
        for (const NegativeFluence& n : find_negative_fluence(d, m.bands, out)) {
            ctx.report.values()["lpm"]["negative_fluence"][n.band] = n.json();
            if (d.rank() == 0)
                log::warn("lpm (band {}): fluence_diffuse is below -{:g} of its largest value {:.3g} in {} cells, "
                          "down to {:.3g}{}",
                          n.band, kNegativeFluenceShare, n.max, n.cells, n.min,
                          opt_.tail == "dsa" ? ": DSA's P1 corrections are not clamped (large |g| makes their "
                                               "current term swing); model.lpm.tail = \"diffusion\" clamps its P1 "
                                               "source at 0"
                                             : "");
        }
    }

private:
    static void check_decomposition(const Decomposition& d) {
        d.require_z_slabs("model lpm", "its z maps are pipelined down the slab chain");
    }

    LpmOptions opt_;
};

}  // namespace

std::unique_ptr<ScatteringModel> make_lpm_model(const LpmOptions& opt) {
    return std::make_unique<LightPropagationMaps>(opt);
}

}  // namespace nimbus
