#include "solvers/diffusion/diffusion.h"

#include <algorithm>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "src/physics/band_groups.h"
#include "solvers/diffusion/linear_solve.h"
#include "solvers/diffusion/solve_diffusion.h"
#include "solvers/diffusion/sources.h"
#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/log.h"
#include "src/physics/lights.h"
#include "src/scene/emission.h"

namespace nimbus {
namespace {

class DiffusionModel final : public ScatteringModel {
public:
    explicit DiffusionModel(const DiffusionOptions& opt) : opt_(opt) { opt_.validate(); }

    std::string name() const override { return "diffusion"; }

    nlohmann::json options() const override { return options_json(opt_); }

    // hypre's 7-point matrix, vectors and multigrid hierarchy, the right-hand sides and the per
    // band fluence and flux: 8 (26 + 4 bands) bytes per local cell, and the escape flux of the
    // sheets under lit faces (3 per right-hand side, counted per band). An upper bound: since the
    // forty-fifth session U, F and the bands' fields are allocated after the solve and the
    // problem is freed before the bands' fields, and since the forty-eighth session the
    // right-hand sides live on the cloud's bounding box (DiffusionProblem::rhs_within): the
    // model's part of the peak (peak minus model single's, 1 rank, 3 bands, 2 right-hand sides,
    // 9 lights, no output; README, "Usage") is 93 MiB on the default cloud (123 before) and 185
    // MiB with a box filling its 96 x 96 x 64 cells, against 252 MiB here. The flux limiter adds
    // 21 values per cell: its copy of the problem for one right-hand side (6), the previous U
    // (1), lambda and its target (2), the Anderson history (12: 5 pairs of differences, the last
    // iterate and residual). SMG's plane solvers and PETSc's copy of the system with BoomerAMG's
    // hierarchy take more: measured on the default cloud (1 rank, peak memory against pfmg-pcg's
    // 292 MiB): smg-pcg +100 MiB, smg +94, petsc +144, i.e. 23 and 33 values per cell (a QA
    // finding: the check counted pfmg-pcg's alone).
    double memory_bytes(const Scene& s, const Decomposition& d, int nlights) const override {
        const double limiter = opt_.flux_limiter == "none" ? 0.0 : 21.0;
        const double solver = opt_.solver.rfind("smg", 0) == 0 ? 23.0 : opt_.solver == "petsc" ? 33.0 : 0.0;
        // The sources step holds the first-scatter means it keeps (FirstScatterMeans), one per light.
        const double kept = std::min(nlights, FirstScatterMeans::kMaxKeptLights);
        return 8.0 * (26.0 + 7.0 * s.nbands() + limiter + solver + kept) * static_cast<double>(d.local().cells());
    }
    // solver = petsc: the decomposition and model.diffusion.petsc_options (linear_solve.h).
    // Warns of settings that run but rarely mean what they say.
    void check_layout(const Decomposition& d) const override {
        if (opt_.solver == "petsc") diffusion::check_petsc_layout(d);
    }
    // Cells of more than kThickCell optical depths. Their first scatter lies in sheets under the
    // lit faces, which make_problem splits between the cell's centre and the face (sources.cpp,
    // sheet_escape), but the field inside them is not resolved. A box of 4³ cells (albedo 0.999,
    // g 0 unless said; Monte Carlo, 2e5 photons; solvers/diffusion/README.md, "Optically thick
    // cells"), total fluence_diffuse at kappa h = 5, 10, 20: 1.08, 1.04, 1.00 under an overhead
    // sun (before the split 2.1, 3.5, 5.9), 1.01, 1.00, 0.98 under a sun 32° from the zenith,
    // 0.97-0.98 under the sky, 1.04, 1.00, 0.96 at albedo 0.9 with g 0.85 (0.79 at 20 with the
    // forward peak's centre value before the fortieth session), rel L2 up to 0.13.
    // Said by rank 0. Collective.
    static constexpr double kThickCell = 4.0;
    static void warn_if_cells_thick(const Decomposition& d, const Medium& m) {
        nimbus::warn_if_cells_thick(d, m, "diffusion", kThickCell,
                                    "the field inside them is not resolved (on a box of such cells the total "
                                    "fluence_diffuse is 0.96-1.08x Monte Carlo's at 5-20 per cell, its rel L2 up to "
                                    "0.13); refine the grid to about 1 per cell");
    }
    void check(const Scene&, const Decomposition& d, const Medium& m) const override {
        check_layout(d);
        if (opt_.solver == "petsc") diffusion::check_petsc(d, opt_);
        // On a periodic axis of N = 2^m M cells (M odd): hypre's SMG needs M = 1 (HYPRE_struct_ls.h,
        // "Struct SMG Solver"; 24 cells periodic in x gave NaN from the first iteration), and PFMG
        // alone converges slowly for a large M (47 cells periodic in x and y: no convergence in 200
        // iterations; 48 = 16 x 3: 20).
        for (int a = 0; a < 3; ++a) {
            const int n = d.global().size(a);
            int odd = n;
            while (odd > 1 && odd % 2 == 0) odd /= 2;
            if (!d.periodic(a) || odd == 1) continue;
            if (opt_.solver == "smg" || opt_.solver == "smg-pcg")
                throw Error(fmt::format("model.diffusion.solver = \"{}\" needs a power-of-two number of cells on "
                                        "a periodic axis (hypre's SMG), and grid.n[{}] = {} along periodic {}; "
                                        "pfmg-pcg (the default) takes any size",
                                        opt_.solver, a, n, "xyz"[a]));
            if (opt_.solver == "pfmg" && odd > kPfmgLargestOddPeriodFactor)
                log::warn("model.diffusion.solver = \"pfmg\" on periodic {} with grid.n[{}] = {} (odd factor {}): "
                          "PFMG alone converges slowly or not at all on such periods; pfmg-pcg (the default) "
                          "converges there", "xyz"[a], a, n, odd);
        }
        if (opt_.max_transport_length > 0 && opt_.max_transport_length < m.grid.h)
            log::warn("model.diffusion.max_transport_length = {:g} m is below the cell size {:g} m: in every cell "
                      "whose transport mean free path is longer (kappa_tr below 1/ℓ) light then diffuses less "
                      "than one cell, stays where it is scattered, and the fluence tends to Q0/sigma_a (0 = the size "
                      "of each piece of cloud; the length is in metres whatever grid.unit is)",
                      opt_.max_transport_length, m.grid.h);
        if (opt_.tolerance < 1e-14)
            log::warn("model.diffusion.tolerance = {:g} is below what double precision usually reaches "
                      "(1e-16 times the system's condition number): the solve may end in 'did not reach'",
                      opt_.tolerance);
    }
    void solve(const SolveContext& ctx, DiffuseSolution& out) override {
        ScopedTimer timer(ctx.report, "diffusion");
        const Decomposition& d = ctx.decomp;
        const Medium& m = ctx.medium;
        warn_if_cells_thick(d, m);
        out = DiffuseSolution{};
        out.closure = RadianceClosure::p1;  // the renderer draws the model's own P1 radiance
        // The bands' fields are allocated once the first linear solve is done: hypre's matrix,
        // vectors and hierarchy are then gone, and the phase's peak memory is the solve's
        // (with U and F likewise, solve_diffusion.cpp, and the problem freed after its solve: the default
        // cloud's peak on 1 rank went from 314 to 225 MiB, forty-fifth session).
        const auto allocate_bands = [&] {
            for (int b = static_cast<int>(out.fluence.size()); b < m.nbands(); ++b) {
                out.fluence.emplace_back(d.local(), 1, 1, 0.0);
                out.flux.emplace_back(d.local(), 1, 3, 0.0);
            }
        };
        // Superposition of the lights' colours needs a linear solve (not the flux limiter); the
        // sum of right-hand sides is clamped, not each of them (clamping is not linear).
        const bool linear = opt_.flux_limiter == "none";
        const std::vector<VolumeSource> sources = volume_sources(ctx.scene);  // [[sources]], q = power / 4π
        check_volume_sources(sources, m.rho, d);
        const auto groups = group_bands(
            m.bands, term_strengths(ctx.light.lights, sources, m.nbands()), linear);
        DiffusionOptions solve_opt = opt_;
        if (linear) solve_opt.clamp_negative = false;
        ctx.report.values()["diffusion"]["matrices"] = groups.size();
        int solves = 0;
        for (size_t g = 0; g < groups.size(); ++g) {
            const auto& group = groups[g];
            const size_t systems_before = system_count(ctx.report);
            diffusion::DiffusionProblem p;
            {
                ScopedTimer t(ctx.report, "sources");
                p = diffusion::make_problem(d, m, ctx.light, sources, group, opt_.delta_scaling, &ctx.report);
            }
            const auto res = [&] {
                if (linear) return diffusion::solve_diffusion(d, p, solve_opt, ctx.report);
                try {  // the limiter's failure names the bands it was solving
                    return diffusion::solve_diffusion(d, p, solve_opt, ctx.report);
                } catch (const Error& e) {
                    throw Error(fmt::format("{}: {}", band_names(group, m), e.what()));
                }
            }();
            p = diffusion::DiffusionProblem{};  // its sources and coefficients are used up
            label_systems(ctx.report, systems_before, g, group, m, ctx.light.lights);
            // Solved only where something scatters (an empty region, or no light: none).
            for (const auto& st : res.stats) solves += st.iterations > 0 ? 1 : 0;
            warn_if_negative(res.stats, group, m);
            ScopedTimer bands_timer(ctx.report, "bands");  // each band's fields from the solutions and the forward peak
            allocate_bands();
            // The forward peak first (every band belongs to one group, so its fields are still 0
            // here), then the solutions, which are zero in empty cells (all cells outside the
            // solve region, and 74% of it on the bench cumulus at 64³).
            diffusion::add_forward_peak(d, m, ctx.light, group, opt_.delta_scaling, out.fluence, out.flux);
            for_each_cell(res.region.box.intersect(d.local()), [&](int i, int j, int k) {
                if (!(m.rho(i, j, k) > 0.0)) return;
                for (const auto& use : group.bands) {
                    double u = 0.0, f[3] = {0.0, 0.0, 0.0};
                    for (const auto& t : use.terms) {
                        u += t.scale * res.U[static_cast<size_t>(t.rhs)](i, j, k);
                        for (int c = 0; c < 3; ++c) f[c] += t.scale * res.flux[static_cast<size_t>(t.rhs)](i, j, k, c);
                    }
                    if (linear && opt_.clamp_negative) u = std::max(u, 0.0);
                    out.fluence[static_cast<size_t>(use.band)](i, j, k) += 4.0 * std::numbers::pi * u;
                    auto& fx = out.flux[static_cast<size_t>(use.band)];
                    for (int c = 0; c < 3; ++c) fx(i, j, k, c) += f[c];
                }
            });
        }
        {
            ScopedTimer t(ctx.report, "bands");
            allocate_bands();  // (every band is in a group, so they are already)
            for (int b = 0; b < m.nbands(); ++b) {
                exchange_halo(out.fluence[static_cast<size_t>(b)], d);
                exchange_halo(out.flux[static_cast<size_t>(b)], d);
            }
        }
        ctx.report.values()["diffusion"]["solves"] = solves;
        ctx.report.values()["diffusion"]["bands"] = m.nbands();
    }

private:
    // P1's U goes slightly negative at a few lit surface cells (|min U| ~ 3e-4 max U on the
    // default cloud); beyond kNegativeWarning x max U the approximation has broken down there
    // (no delta scaling: -0.24 x max on a 48 x 48 x 32 cloud, -5 x with the flux limiter), and
    // the clamp to zero in the output would hide it.
    // "band r" or "bands r, g, b": the bands a group's solve serves, for messages.
    static std::string band_names(const BandGroup& group, const Medium& m) {
        std::vector<std::string> names;
        for (const auto& use : group.bands) names.push_back(m.bands[static_cast<size_t>(use.band)].name);
        return fmt::format("{} {}", names.size() == 1 ? "band" : "bands", fmt::join(names, ", "));
    }
    // The report's diffusion.systems entries from `from` on, one per linear solve of this group
    // (matrix g): which bands use the right-hand side and which source terms it holds (lights by
    // name, "sky" for its directions; volume sources as "sources[i]"), so that a solve's
    // iterations and times can be traced to the light and bands they are for.
    static size_t system_count(Report& report) {
        const nlohmann::json& rec = report.values()["diffusion"];
        return rec.contains("systems") ? rec["systems"].size() : 0;
    }
    static void label_systems(Report& report, size_t from, size_t g, const BandGroup& group,
                              const Medium& m, const std::vector<DirectionalLight>& lights) {
        if (system_count(report) == from) return;
        nlohmann::json& systems = report.values()["diffusion"]["systems"];
        for (size_t e = from; e < systems.size(); ++e) {
            const size_t rhs = systems[e]["rhs"].get<size_t>();
            const std::vector<double>& weight = group.rhs_weights[rhs];
            systems[e]["matrix"] = g;
            systems[e]["bands"] = rhs_band_names(group, rhs, m.bands);
            systems[e]["terms"] = term_names(weight, lights, weight.size() - lights.size());
        }
    }
    static constexpr double kNegativeWarning = 0.05;
    static constexpr int kPfmgLargestOddPeriodFactor = 8;
    void warn_if_negative(const std::vector<diffusion::SolveStats>& stats, const BandGroup& group,
                          const Medium& m) const {
        for (const auto& st : stats) {
            if (!(st.min_U < -kNegativeWarning * st.max_U)) continue;
            log::warn("diffusion ({}): U is negative in {} cells, down to {:.3g} against a largest U of {:.3g}{}: "
                      "P1 does not hold there (a first-scatter flux source too strong for it{}), and fluence_diffuse "
                      "is unreliable in and around those cells",
                      band_names(group, m), st.negative_boundary_cells + st.negative_interior_cells, st.min_U, st.max_U,
                      opt_.clamp_negative ? " (set to 0 in the output: model.diffusion.clamp_negative)" : "",
                      opt_.delta_scaling ? "" : "; model.diffusion.delta_scaling = true reduces it");
            return;
        }
    }

    DiffusionOptions opt_;
};

}  // namespace

std::unique_ptr<ScatteringModel> make_diffusion_model(const DiffusionOptions& opt) {
    return std::make_unique<DiffusionModel>(opt);
}

}  // namespace nimbus
