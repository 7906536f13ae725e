#include "solvers/dom/dom.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/band_problem.h"
#include "solvers/dom/iteration.h"
#include "solvers/dom/transport_sweep.h"
#include "src/core/convergence_outlook.h"
#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/log.h"
#include "src/core/progress.h"
#include "src/core/report.h"
#include "src/core/residual_history.h"
#include "src/physics/angular_moments.h"
#include "src/physics/band_groups.h"
#include "src/scene/emission.h"

namespace nimbus {
namespace {

// The uncollided sky of optics o on the quadrature: the sky boundary radiance alone (no volume
// source, no scattering) with the true extinction kappa = rho sigma_t, swept from cleared
// reflected planes. A low mirror face returns a sweep's own light; a high one the previous
// sweep's (transport_sweep.h), so with a high mirror the sweep is repeated until the reflected
// light settles (each repeat carries it one reflection further: a few sweeps, more between
// facing mirrors). With one sweep only, a high mirror reflected none of it and the sky it did
// reflect stayed in fluence_diffuse: 0.28 of 2πL in a pure absorber (a QA finding). The
// periodic planes start from the solve's last sweep. Collective over d.comm().
void uncollided_sky(const Decomposition& d, const Medium& m, const BandOptics& o, dom::TransportSweeper& sweeper,
                    dom::SweepOutput& unc) {
    const Box own = m.rho.owned();
    Field<double> kappa(own, 0, 1, 0.0), no_light(own, 0, 1, 0.0);
    for_each_cell(own, [&](int i, int j, int k) { kappa(i, j, k) = m.rho(i, j, k) * o.sigma_t; });
    const dom::SourceRows no_source(own, {});  // no cell has a source or needs moments
    dom::SweepSource src;
    src.kappa = &kappa;
    src.rows = &no_source;  // moments: none
    src.amp = &no_light;  // non-null: this sweep carries the boundary source
    src.nl = 0;
    sweeper.reset_reflections();
    sweeper.sweep(src, unc);
    const auto& mirror = sweeper.boundary().reflective;
    if (!(mirror[1] || mirror[3] || mirror[5])) return;
    constexpr int kMaxSweeps = 1000;
    constexpr double kSettled = 1e-13;  // relative change of the fluence, max norm
    double change = 0.0;
    for (int sweep = 1; sweep < kMaxSweeps; ++sweep) {
        const Field<double> before = unc.fluence;
        sweeper.sweep(src, unc);
        double diff[2] = {0.0, 0.0};  // max |change|, max |fluence|
        for_each_cell(own, [&](int i, int j, int k) {
            diff[0] = std::max(diff[0], std::abs(unc.fluence(i, j, k) - before(i, j, k)));
            diff[1] = std::max(diff[1], std::abs(unc.fluence(i, j, k)));
        });
        MPI_Allreduce(MPI_IN_PLACE, diff, 2, MPI_DOUBLE, MPI_MAX, d.comm());
        change = diff[1] > 0 ? diff[0] / diff[1] : 0.0;
        if (change <= kSettled) return;
    }
    if (d.rank() == 0)
        log::warn("dom: the uncollided sky between the mirror faces changed by {:.2g} (relative) after {} sweeps; "
                  "fluence_diffuse keeps that much of it",
                  change, kMaxSweeps);
}

// The first-collision source comes from the light pass, which knows nothing of mirror faces:
// a beam crossing one enters it unattenuated (as from vacuum, where the mirror image of the
// medium should have shadowed it) or leaves through it unreflected. Exact only for beams
// parallel to every mirror face; the sky's bins cross every side face. Measured on a cloud with
// an x+ or x- mirror against the mirror-doubled domain (sky first-collision, albedo 0.9): rel L2
// 4.2e-2; with sky = "boundary", 1e-8. Said by rank 0. Not collective.
void warn_if_lights_cross_mirrors(const Decomposition& d, const dom::SweepBoundary& bc, const LightTransport& lights) {
    static const char* kFace[6] = {"x-", "x+", "y-", "y+", "z-", "z+"};
    std::vector<std::string> faces;
    bool sky = false, sun = false;
    for (int f = 0; f < 6; ++f) {
        if (!bc.reflective[static_cast<size_t>(f)]) continue;
        bool crossed = false;
        for (const DirectionalLight& l : lights.lights)
            if (std::abs(l.w[f / 2]) > 1e-12) {
                crossed = true;
                (l.name == "sun" ? sun : sky) = true;
            }
        if (crossed) faces.push_back(kFace[f]);
    }
    if (faces.empty() || d.rank() != 0) return;
    log::warn("dom: the {} crosses the mirror face{} {}: its first-collision source treats them as open (its beams "
              "enter there unshadowed by the medium's mirror image and leave unreflected), so the fields near them "
              "are off (4% rel L2 on a test cloud with the sky); {}",
              sun && sky ? "sun and sky light" : sun ? "sunlight" : "sky light", faces.size() == 1 ? "" : "s",
              fmt::format("{}", fmt::join(faces, ", ")),
              sky ? "sky = \"boundary\" brings the sky in through the open faces and reflects it exactly"
                  : "a sun parallel to the mirror faces is exact");
}

class DiscreteOrdinates final : public ScatteringModel {
    // DSA (dsa.h) is built for the step scheme (D = 1/(3 kappa_tr) + h/4): with diamond it
    // slows down from ~1.5 mean free paths per cell and diverges from ~2 (tau-100 cube, a 0.999:
    // 11, 15, 34 iterations at kappa h = 0.5, 1, 1.5; change ~1.3 per iteration at 2 and 6.25).
    // DSA-preconditioned GMRES converges there (26 iterations at 6.25): an Error names it.
    void check_diamond_dsa(const Decomposition& d, const dom::BandProblem& p) const {
        if (opt_.scheme != "diamond" || opt_.iteration != "dsa") return;
        double thick = 0.0;
        for_each_cell(p.kappa.owned(), [&](int i, int j, int k) { thick = std::max(thick, p.kappa(i, j, k) * p.h); });
        refuse_diamond_dsa_beyond(d, thick);
    }
    // Collective: thick = this rank's max kappa* h (delta-M scaled).
    void refuse_diamond_dsa_beyond(const Decomposition& d, double thick) const {
        MPI_Allreduce(MPI_IN_PLACE, &thick, 1, MPI_DOUBLE, MPI_MAX, d.comm());
        if (thick >= kDiamondDsaMaxCellTau)
            throw Error(fmt::format("model.dom.scheme = 'diamond' with iteration = 'dsa' diverges on cells this thick "
                                    "(max kappa* h = {:.2f} >= {}): use iteration = 'gmres' (DSA-preconditioned) or "
                                    "scheme = 'step'", thick, kDiamondDsaMaxCellTau));
    }
    static constexpr double kDiamondDsaMaxCellTau = 2.0;
    // Cells of more than kThickCell optical depths (as the diffusion model): the step scheme
    // spreads a lit cell's first scatter over the whole cell, and with absorption its light is
    // absorbed on its way out. A box of 4³ cells under an overhead sun (g 0; Monte Carlo, 4e5
    // photons; solvers/diffusion/README.md, "Optically thick cells"), total fluence_diffuse over
    // the cells at kappa h = 5 and 20: 0.80, 0.99 at albedo 0.999, 1.19, 1.57 at 0.9, 1.16, 1.26
    // at 0.5 (S8 within 0.01 of S4). Said by rank 0. Collective.
    static constexpr double kThickCell = 4.0;
    static void warn_if_cells_thick(const Decomposition& d, const Medium& m) {
        nimbus::warn_if_cells_thick(d, m, "dom", kThickCell,
                                    "the field inside them is not resolved, and where they absorb their first "
                                    "scatter is absorbed on its way out (on a box of such cells the total "
                                    "fluence_diffuse is 0.80-0.99x Monte Carlo's at albedo 0.999, 1.2-1.6x at 0.9, "
                                    "at 5-20 per cell); refine the grid (to well under 1 per cell where the albedo "
                                    "is near 1: see the step scheme's warning)");
    }
    // The step scheme's diffusion limit has D = 1/(3 kappa_tr) + h/4 (the numerical diffusion of
    // upwinding; dsa.h uses the same D): in a cell of transport depth kappa_tr h = kappa (1 - a g) h
    // light diffuses (3/4) kappa_tr h more than it should, and where it scatters many times before
    // it leaves or is absorbed, the excess lets it out too soon. Measured (S4, 2 ranks, Monte Carlo
    // with 4e5 photons on the box, 2e6 on the cloud; total fluence_diffuse over the cells):
    // - a box 20 mean free paths wide (4 m in an 8 m domain, albedo 0.999, g 0) at kappa h = 0.31,
    //   0.62, 1.25, 5: 0.85, 0.75, 0.63, 0.43 of Monte Carlo's under a volume source filling it and
    //   0.88, 0.83, 0.78, 0.80 under an overhead sun (first order in h); diamond 0.99, 0.98
    //   (source) and 1.03, 1.51 (sun) at 1.25 and 5; at albedo 0.9, step 0.91 and 1.01 at 1.25;
    // - the default cumulus (g 0.85) at 25, 50, 100 m cells (excess 11%, 23%, 45%): 0.99, 0.97,
    //   0.95, rel L2 0.053, 0.059, 0.089 (the noise of references of 2e6 photons included; 0.037
    //   at 25 m against the study's 2e7).
    // Warned above kStepExcessDiffusion for bands of albedo >= kBrightAlbedo (the study's scenes
    // have at most 0.11). Said by rank 0. Collective.
    static constexpr double kStepExcessDiffusion = 0.4, kBrightAlbedo = 0.95;
    void warn_if_step_diffuses(const Decomposition& d, const Medium& m) const {
        if (opt_.scheme != "step") return;
        const double rho_max = max_density(d, m);
        double excess = 0.0;
        const BandOptics* worst = nullptr;
        for (const BandOptics& o : m.bands) {
            const double e = 0.75 * rho_max * o.sigma_t * (1.0 - o.albedo * o.g) * m.grid.h;
            if (o.albedo >= kBrightAlbedo && e > excess) excess = e, worst = &o;
        }
        if (worst == nullptr || excess <= kStepExcessDiffusion || d.rank() != 0) return;
        log::warn("model dom: the step scheme diffuses light {:.0f}% more than it should in the cells of largest "
                  "transport depth (kappa (1 - a g) h = {:.3g}, band '{}', albedo {:g}), so where light scatters many "
                  "times fluence_diffuse comes out low (the default cumulus at 100 m cells, 45%: total 0.95 of Monte "
                  "Carlo's, rel L2 0.089 against 0.053 at 25 m; a box 20 mean free paths wide at albedo 0.999 and "
                  "g 0, kappa h = 1.25: 0.63 under volume emission, 0.78 under the sun); scheme = 'diamond' gave "
                  "0.99 and 1.03 on that box (with iteration = 'gmres' from 2 optical depths per cell), or refine "
                  "the grid",
                  100.0 * excess, excess / 0.75, worst->name, worst->albedo);
    }

public:
    explicit DiscreteOrdinates(const DomOptions& opt) : opt_(opt) { opt_.validate(); }
    std::string name() const override { return "dom"; }
    nlohmann::json options() const override { return options_json(opt_); }
    void solve(const SolveContext& ctx, DiffuseSolution& out) override;
    // Peak = about twice the state (3 moment arrays, angular fluxes of the largest octant, the
    // band's coefficients, the light sources: state_bytes_per_cell below) per local cell, measured
    // 1.95x and 2.01x on the default cloud at S4 L3 and S8 L7 when the moments covered every cell.
    // Since the twenty-ninth session they cover only the cells that scatter (the source rows,
    // transport_sweep.h), which the estimate cannot know before the medium is read: it counts
    // every cell, an upper bound (870 -> 681 MiB measured at S4 L3). GMRES adds its Krylov basis, up to
    // 31 vectors of all moments (restart 30) of the cells that scatter (the source rows; counted
    // here for every cell, an upper bound), and periodic x/y the kept ghost planes.
    // Before the light pass: the decomposition the sweeps need, and diamond with DSA on cells too
    // thick for it (check_diamond_dsa, from the medium: kappa* = (1 - a f) rho sigma_t of every band).
    void check_layout(const Decomposition& d) const override { dom::check_sweep_decomposition(d); }
    void check(const Scene&, const Decomposition& d, const Medium& m) const override {
        check_layout(d);
        for (const std::string& face : opt_.reflective)  // "x-" ... "z+", validated with the options
            if (d.periodic(face[0] - 'x'))
                throw Error(fmt::format("dom: face {} cannot be both reflective and periodic", face));
        if (opt_.scheme != "diamond" || opt_.iteration != "dsa") return;
        const dom::AngularSet ang = dom::make_angular_set(opt_);
        double rho_max = 0.0;
        for_each_cell(d.local(), [&](int i, int j, int k) { rho_max = std::max(rho_max, m.rho(i, j, k)); });
        double thick = 0.0;
        for (const BandOptics& o : m.bands) {
            const double f = hg_legendre(o.g, ang.L, opt_.delta_m).f;
            thick = std::max(thick, delta_m_sigma_t_scale(o.albedo, f) * o.sigma_t * rho_max * m.grid.h);
        }
        refuse_diamond_dsa_beyond(d, thick);
    }
    double memory_bytes(const Scene&, const Decomposition& d, int nlights) const override {
        const dom::AngularSet ang = dom::make_angular_set(opt_);
        double per_cell = 2.0 * state_bytes_per_cell(ang, nlights);
        // Every octant in flight beyond the first has its own psi and source (transport_sweep.h;
        // octant_overlap, default 8): 7 x 2 x 36 values per cell at S16, which the estimate missed
        // until a QA run peaked at 2.3x it (311 MiB against 134 at 40 x 40 x 32).
        per_cell += 8.0 * (std::max(1, opt_.octant_overlap) - 1) * ((opt_.scheme == "diamond" ? 4 : 1) + 1) *
                    ang.max_octant_size;
        if (opt_.iteration == "gmres" || opt_.iteration == "gmres-plain")
            per_cell += 8.0 * ang.nmom * (std::min(opt_.max_iterations, 30) + 1);
        // Periodic x/y: every direction's ghost plane per periodic axis is kept between sweeps.
        const Box& own = d.local();
        const double planes = (d.periodic(0) ? own.size(1) : 0) + (d.periodic(1) ? own.size(0) : 0);
        return per_cell * static_cast<double>(own.cells()) + 8.0 * ang.quadrature.size() * planes * own.size(2);
    }

private:
    double state_bytes_per_cell(const dom::AngularSet& ang, int nlights) const {
        return 8.0 * (3 * ang.nmom + (opt_.scheme == "diamond" ? 4 : 1) * ang.max_octant_size + 8 +
                      2 * std::max(1, nlights));
    }
    DomOptions opt_;
};

// Boundaries: the reflective faces, and the sky as incoming radiance (then not a first-collision term).
dom::SweepBoundary sweep_boundary(const DomOptions& opt, const Scene& scene) {
    dom::SweepBoundary bc;
    for (const std::string& f : opt.reflective)
        bc.reflective[static_cast<size_t>(2 * (f[0] - 'x') + (f[1] == '+' ? 1 : 0))] = true;
    bc.sky = opt.sky == "boundary" && !scene.sky.radiance.empty();
    return bc;
}

// Emission q = Σ_t weight[nl + t] power_t / 4π of the volume sources, for one right-hand side.
void set_emission(dom::BandProblem& p, const std::vector<VolumeSource>& sources, const Field<double>& rho,
                  const std::vector<double>& weight, size_t nl) {
    if (sources.empty()) return;
    for_each_cell(p.emission.owned(), [&](int i, int j, int k) {
        const double e =
            emitted_power_at(sources, rho, [&](size_t t) { return weight[nl + t]; }, i, j, k, {i, j, k});
        p.emission(i, j, k) = e / (4.0 * std::acos(-1.0));
    });
}

// Level-symmetric S_N integrates the products of the moments up to Legendre order N - 1, the
// usual pairing (solvers/dom/README.md); beyond it the scattering source is aliased. On
// sphere_ground at 24x24x16, S4 with L = 8 took the rel. L2 error against Monte Carlo (10^7
// photons) from 0.045-0.050 (L = 3) to 0.19, and at g = -0.99 source iteration and DSA diverge
// for every L >= 4.
bool beyond_quadrature(const DomOptions& opt) {
    return opt.quadrature == "level-symmetric" && opt.legendre_order > opt.order - 1;
}

// A solve that did not converge is an error on every rank, with its history and what to try.
[[noreturn]] void throw_not_converged(const DomOptions& opt, const dom::IterationResult& res,
                                      const std::string& for_bands) {
    if (res.stalled)
        throw Error(fmt::format("dom: the solve of {} diverges with iteration = \"{}\": {} (relative change {}); "
                                "use model.dom.iteration = \"gmres\" (DSA-preconditioned GMRES){}",
                                for_bands, opt.iteration, res.divergence, format_history(res.history),
                                beyond_quadrature(opt) ? fmt::format(", or model.dom.legendre_order <= {} (what S{} integrates)",
                                                                     opt.order - 1, opt.order)
                                                       : std::string()));
    throw Error(fmt::format("dom: the solve of {} did not converge in {} {} iterations (tolerance {:.1e}); "
                            "relative change: {}; raise model.dom.max_iterations{}",
                            for_bands, res.iterations, opt.iteration, opt.tolerance, format_history(res.history),
                            opt.iteration == "gmres" ? "" : " or use model.dom.iteration = \"gmres\""));
}

// Energy balance of the scaled problem into the solve's report entry: emitted + first-collision
// = absorbed + net leakage (light that came in through the faces, the sky as boundary radiance or
// a mirror, counts against it), relative to the external power: the sources and the sky's
// incoming light. Collective.
void record_energy_balance(const Decomposition& d, double cell_volume, const dom::BandProblem& p,
                           const dom::SweepOutput& sw, nlohmann::json& entry) {
    double e[2] = {0.0, 0.0};
    for_each_cell(d.local(), [&](int i, int j, int k) {
        double src = 4.0 * std::acos(-1.0) * p.emission(i, j, k);
        for (int l = 0; l < p.nl; ++l) src += p.amp(i, j, k, l);
        e[0] += cell_volume * src;
        e[1] += cell_volume * p.sigma_a(i, j, k) * sw.fluence(i, j, k);
    });
    MPI_Allreduce(MPI_IN_PLACE, e, 2, MPI_DOUBLE, MPI_SUM, d.comm());
    double leaked = 0.0;
    for (double v : sw.leakage) leaked += v;
    entry["source_power"] = e[0];
    entry["sky_incoming_power"] = sw.sky_incoming;
    entry["absorbed_power"] = e[1];
    entry["leakage"] = sw.leakage;
    const double power_in = e[0] + sw.sky_incoming;
    entry["energy_balance"] = power_in > 0 ? (e[0] - e[1] - leaked) / power_in : 0.0;
}

// Each band that uses right-hand side r of the group adds that solution at its scale: the
// iteration's fluence and flux plus the delta-M forward peak, less the uncollided sky (unc, when
// the sky is boundary radiance and lit).
void add_to_bands(const BandGroup& group, size_t r, const dom::BandProblem& p, const dom::SweepOutput& sw,
                  const dom::SweepOutput* unc, DiffuseSolution& out) {
    for_each_use(group, r, [&](int band, double scale) {
        Field<double>& fl = out.fluence[static_cast<size_t>(band)];
        Field<double>& fx = out.flux[static_cast<size_t>(band)];
        for_each_cell(p.kappa.owned(), [&](int i, int j, int k) {
            fl(i, j, k) += scale * (sw.fluence(i, j, k) + p.forward_fluence(i, j, k) - (unc ? unc->fluence(i, j, k) : 0.0));
            for (int c = 0; c < 3; ++c)
                fx(i, j, k, c) += scale * (sw.flux(i, j, k, c) + p.forward_flux(i, j, k, c) -
                                           (unc ? unc->flux(i, j, k, c) : 0.0));
        });
    });
}

// Negative fluence_diffuse (the truncated phase function's negative lobes: strong backscattering,
// or a forward peak without delta-M; solvers/dom/README.md) below -kNegativeFluenceShare of a
// band's largest value: into the report (negative_fluence per band) and a warning on rank 0.
// Collective.
void report_negative_fluence(const Decomposition& d, const std::vector<BandOptics>& bands, const DomOptions& opt,
                             const DiffuseSolution& out, nlohmann::json& rec) {
    for (const NegativeFluence& n : find_negative_fluence(d, bands, out)) {
        rec["negative_fluence"][n.band] = n.json();
        const BandOptics& bo = *std::find_if(bands.begin(), bands.end(), [&](const BandOptics& o) { return o.name == n.band; });
        if (d.rank() == 0)
            log::warn("dom (band {}): fluence_diffuse is below -{:g} of its largest value {:.3g} in {} cells, down to "
                      "{:.3g}: the phase function truncated at legendre_order {} has negative lobes (g = {:g}{}); {}",
                      n.band, kNegativeFluenceShare, n.max, n.cells, n.min, opt.legendre_order, bo.g,
                      opt.delta_m ? "" : ", without delta-M",
                      !opt.delta_m && bo.g > 0.0
                          ? "model.dom.delta_m = true (the default) takes the forward peak out of it"
                          : "a higher order with legendre_order = N - 1 (e.g. order = 8, legendre_order = 7) "
                            "reduces them");
    }
}

// Figures of merit into values()["dom"] (Kripke's grind time: time / (global unknowns x
// iterations): per unknown of the whole grid, so sweeping only the medium's box lowers it; the
// solves' swept_cell_fraction says by how much), and the log line. Collective.
void record_figures_of_merit(const Decomposition& d, const dom::TransportSweeper& sweeper,
                             const dom::AngularSet& ang, double iter_seconds, double unknown_iterations,
                             nlohmann::json& rec) {
    const dom::SweepTiming& t = sweeper.timing();
    double tm[3] = {t.sweep_seconds, t.wait_seconds, t.moment_seconds};
    double eff = t.sweep_seconds > 0 ? 1.0 - t.wait_seconds / t.sweep_seconds : 1.0;
    MPI_Allreduce(MPI_IN_PLACE, tm, 3, MPI_DOUBLE, MPI_MAX, d.comm());
    MPI_Allreduce(MPI_IN_PLACE, &eff, 1, MPI_DOUBLE, MPI_MIN, d.comm());
    rec["grind_time_ns"] = unknown_iterations > 0 ? 1e9 * iter_seconds / unknown_iterations : 0.0;
    rec["sweep_grind_time_ns"] = unknown_iterations > 0 ? 1e9 * tm[0] / unknown_iterations : 0.0;
    rec["sweep_seconds"] = tm[0];
    rec["pipeline_wait_seconds"] = tm[1];
    rec["moment_seconds"] = tm[2];  // sources from moments and moments from psi (moment_kernels.h)
    rec["sweep_efficiency"] = eff;
    rec["periodic_passes"] = t.periodic_passes;
    std::int64_t fixups = t.fixups;  // diamond: cell-directions fixed up, all ranks
    MPI_Allreduce(MPI_IN_PLACE, &fixups, 1, MPI_INT64_T, MPI_SUM, d.comm());
    rec["fixups"] = fixups;
    if (d.rank() == 0)
        log::info("dom: {} on {}, grind time {:.2f} ns, sweep efficiency {:.2f}", ang.quadrature.name,
                  d.describe(), rec["grind_time_ns"].get<double>(), eff);
}

void DiscreteOrdinates::solve(const SolveContext& ctx, DiffuseSolution& out) {
    ScopedTimer timer(ctx.report, "dom");
    const Decomposition& d = ctx.decomp;
    const Medium& m = ctx.medium;
    warn_if_cells_thick(d, m);
    warn_if_step_diffuses(d, m);
    const dom::AngularSet ang = dom::make_angular_set(opt_);
    sweep::SweepOptions sopt;
    sopt.tile_rows = opt_.tile_rows;
    sopt.octant_overlap = opt_.octant_overlap;
    const dom::SweepBoundary bc = sweep_boundary(opt_, ctx.scene);
    const LightTransport first_collision = bc.sky ? dom::without_sky(ctx.light) : LightTransport{};
    const LightTransport& lights = bc.sky ? first_collision : ctx.light;
    warn_if_lights_cross_mirrors(d, bc, lights);
    const dom::SpatialScheme scheme = opt_.scheme == "diamond" ? dom::SpatialScheme::diamond : dom::SpatialScheme::step;
    dom::TransportSweeper sweeper(d, ang, m.grid.h, sopt, 0.1 * opt_.tolerance, scheme, bc);
    if (beyond_quadrature(opt_) && d.rank() == 0)
        log::warn("model.dom.legendre_order = {} is beyond what S{} integrates (Legendre order {}): the scattering "
                  "source is aliased, which costs accuracy and can make the iteration diverge under strong "
                  "backscattering; use legendre_order <= {} or a higher order", opt_.legendre_order, opt_.order,
                  opt_.order - 1, opt_.order - 1);
    auto& rec = ctx.report.values()["dom"];
    rec["quadrature"] = ang.quadrature.name;
    rec["directions"] = ang.quadrature.size();
    rec["moments"] = ang.nmom;
    rec["scheme"] = opt_.scheme;
    rec["state_bytes_per_cell"] = state_bytes_per_cell(ang, static_cast<int>(ctx.light.lights.size()));
    const std::vector<VolumeSource> sources = volume_sources(ctx.scene);  // [[sources]], q = power / 4π
    check_volume_sources(sources, m.rho, d);
    // Source terms (src/physics/band_groups.h): the first-collision lights, the volume sources
    // and, with the sky as boundary radiance, the sky. The transport is linear in them, so bands
    // with equal optics share one problem per colour of the sources: the default cloud's three
    // bands are two solves, the sun and the sky.
    std::vector<std::vector<double>> strength = term_strengths(lights.lights, sources, m.nbands());
    const size_t nl = lights.lights.size(), sky_term = strength.size();
    if (bc.sky) {
        std::vector<double> L;
        for (int b = 0; b < m.nbands(); ++b) L.push_back(band_value(ctx.scene.sky.radiance, b));
        strength.push_back(std::move(L));
    }
    const std::vector<BandGroup> groups = group_bands(m.bands, strength);
    const Box& own = d.local();
    out = DiffuseSolution{};
    for (int b = 0; b < m.nbands(); ++b) {
        out.fluence.emplace_back(own, 1, 1, 0.0);
        out.flux.emplace_back(own, 1, 3, 0.0);
    }
    rec["solves"] = nlohmann::json::array();
    double iter_seconds = 0, unknown_iterations = 0;
    // Progress (rank 0, from 2 s on): solves done plus the current one's way to the tolerance,
    // ETA from its convergence rate (run_outlook, src/core/convergence_outlook.h).
    int nsolves = 0, solves_done = 0;
    for (const BandGroup& group : groups) nsolves += static_cast<int>(group.rhs_weights.size());
    Progress progress("dom", nsolves, d.rank() == 0);
    double solves_seconds = 0.0;  // of the completed solves
    for (const BandGroup& group : groups)
        for (size_t r = 0; r < group.rhs_weights.size(); ++r) {
            const double solve_start = wall_time();
            const std::vector<double>& weight = group.rhs_weights[r];
            const std::vector<std::string> band_names = rhs_band_names(group, r, m.bands);
            nlohmann::json entry = {{"bands", band_names},
                                    {"terms", term_names(weight, lights.lights, sources.size())}};
            dom::BandProblem p = dom::make_band_optics(m, group.optics, own, ang, opt_.delta_m);
            check_diamond_dsa(d, p);
            dom::add_light_sources(p, d, m, lights, group.optics,
                                   std::vector<double>(weight.begin(), weight.begin() + static_cast<std::ptrdiff_t>(nl)), ang)
                .report(fmt::format("{}", fmt::join(band_names, ", ")), ctx.report);
            set_emission(p, sources, m.rho, weight, nl);
            sweeper.reset_reflections();
            sweeper.reset_periodic_planes();
            if (bc.sky) sweeper.set_sky_radiance(weight[sky_term]);
            dom::SweepOutput sw;
            const std::string what = fmt::format("solve {} of {} (bands {}; {})", solves_done + 1, nsolves,
                                                 fmt::join(band_names, ", "),
                                                 fmt::join(entry["terms"].get<std::vector<std::string>>(), ", "));
            double first_seconds = 0.0;  // when the first iteration (with DSA's set-up) ended
            const dom::IterationMonitor monitor = [&](const std::vector<double>& history) {
                const double seconds = wall_time() - solve_start;  // the clock of solves_seconds
                if (history.size() == 1) first_seconds = seconds;
                const RunOutlook o = run_outlook(history, opt_.tolerance, seconds, first_seconds, solves_done,
                                                 solves_seconds, nsolves);
                progress.update(o.fraction * nsolves, o.seconds_left, fmt::format("tolerance {:.0e}", opt_.tolerance),
                                fmt::format("{}, iteration {}, relative change {:.2e}", what, history.size(),
                                            history.back()));
            };
            const dom::SweepTiming before = sweeper.timing();
            const dom::IterationResult res = dom::iterate_band(d, sweeper, ang, p, opt_.iteration, opt_.tolerance,
                                                               opt_.max_iterations, sw, ctx.report, monitor);
            entry["converged"] = res.converged;
            entry["iterations"] = res.iterations;
            entry["history"] = res.history;
            if (!res.converged) {
                rec["solves"].push_back(entry);
                throw_not_converged(opt_, res, fmt::format("{} {}", band_names.size() == 1 ? "band" : "bands",
                                                           fmt::join(band_names, ", ")));
            }
            double seconds = res.seconds;
            MPI_Allreduce(MPI_IN_PLACE, &seconds, 1, MPI_DOUBLE, MPI_MAX, d.comm());
            iter_seconds += seconds;
            unknown_iterations += static_cast<double>(d.global().cells()) * ang.quadrature.size() * res.iterations;
            entry["dsa_linear_iterations"] = res.dsa_linear_iterations;
            // The solve's sweeps and the share of the grid they covered (the medium's box, then the
            // whole domain once).
            const int sweeps = sweeper.timing().sweeps - before.sweeps;
            entry["sweeps"] = sweeps;
            entry["swept_cell_fraction"] = sweeps > 0 ? (sweeper.timing().swept_cells - before.swept_cells) /
                                                            (sweeps * static_cast<double>(d.global().cells()))
                                                      : 0.0;
            entry["delta_m_f"] = p.phase.f;
            entry["seconds"] = seconds;
            record_energy_balance(d, m.grid.cell_volume(), p, sw, entry);
            rec["solves"].push_back(entry);
            // Sky as boundary radiance: psi holds the uncollided sky too; DESIGN's fluence_diffuse
            // excludes it, so subtract the discrete uncollided sky (one sweep, true kappa: the
            // delta-M forward peak of the sky stays in, as for the first-collision terms).
            dom::SweepOutput unc;
            const bool sky_lit = bc.sky && weight[sky_term] != 0.0;
            if (sky_lit) uncollided_sky(d, m, group.optics, sweeper, unc);
            add_to_bands(group, r, p, sw, sky_lit ? &unc : nullptr, out);
            ++solves_done;
            solves_seconds += wall_time() - solve_start;
        }
    progress.finish();
    report_negative_fluence(d, m.bands, opt_, out, rec);
    for (int b = 0; b < m.nbands(); ++b) {
        exchange_halo(out.fluence[static_cast<size_t>(b)], d);
        exchange_halo(out.flux[static_cast<size_t>(b)], d);
    }
    record_figures_of_merit(d, sweeper, ang, iter_seconds, unknown_iterations, rec);
}

}  // namespace

std::unique_ptr<ScatteringModel> make_dom_model(const DomOptions& opt) {
    return std::make_unique<DiscreteOrdinates>(opt);
}

}  // namespace nimbus
