#include "solvers/diffusion/sources.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "solvers/diffusion/delta_scaling.h"
#include "solvers/diffusion/diffusion_kernel.h"
#include "solvers/diffusion/solve_region.h"
#include "src/core/halo.h"

namespace nimbus::diffusion {

namespace {

// A full cell as the sheets under its lit faces see it: optical thickness (delta-scaled
// extinction), D and sigma_a of the P1 equation, edge.
struct SheetCell {
    double kappa_h, D, sigma_a, h;
};

// The first scatter of one light in a full cell, split into the sheets under the faces it enters
// by: per axis a, the share of the cell's source (weight x <T'>, `mean`) that lies under the
// Marshak face the light enters by on that axis (t_in[a] >= 0: the T' arriving there; -1: the
// face is interior or the light runs parallel to it) and leaves through it directly. A sheet
// brings |w_a| T_in h² and keeps (1 - e^{-kappa h / |w_a|}) of it (all of it in a thick cell,
// where the sheets are the whole source, and about the cell's source in a thin one, where the
// shares are scaled to sum to at most 1); its light falls off as e^{-kappa x / |w_a|} with the
// depth x, so its centroid lies (h/2) L(kappa h / (2 |w_a|)) from the centre toward the face, and
// marshak_escape gives the share that leaves. `strength` (weight x the bound's scale) converts
// a sheet's power per h² to the units of mean. Without this the sheet's light sits at the
// centre, half a cell under the face, behind the half cell's diffusion resistance h / (2D): the
// model came out 2.1x too bright at kappa h = 5 and 5.9x at 20 (a box, albedo 0.999, against
// Monte Carlo; solvers/diffusion/README.md, "Optically thick cells").
std::array<double, 3> sheet_escape(const SheetCell& c, const Vec3& w, const std::array<double, 3>& t_in,
                                   double strength, double mean) {
    std::array<double, 3> share{}, out{};
    double sheets = 0.0;
    for (int a = 0; a < 3; ++a) {
        if (t_in[a] < 0.0) continue;
        const double x = c.kappa_h / std::abs(w[a]);  // the sheet's optical depth across the cell
        share[a] = strength * std::abs(w[a]) * t_in[a] * -std::expm1(-x);
        sheets += share[a];
        // What leaves is below d / (2D) <= (h x / 12) / (2D) (L(y) <= y/3): skip the functions
        // where that is below 1e-9 (thin cells, most of a cloud's surface).
        if (c.h * x / (24.0 * c.D) < 1e-9) continue;
        out[a] = marshak_escape(0.5 * c.h * langevin(0.5 * x), c.D, c.sigma_a, c.h);
    }
    if (!(sheets > 0.0)) return {};
    const double whole = std::max(c.kappa_h * mean, sheets);  // the cell's source per h²
    for (int a = 0; a < 3; ++a) out[a] *= share[a] / whole;
    return out;
}

}  // namespace

DiffusionProblem make_problem(const Decomposition& d, const Medium& m, const LightTransport& light,
                              const std::vector<VolumeSource>& sources, const BandGroup& group,
                              bool delta_scaling, Report* report) {
    const BandOptics& o = group.optics;
    const DeltaScaledOptics s = delta_scale(o.sigma_t, o.albedo, o.g, delta_scaling);
    DiffusionProblem p;
    p.h = m.grid.h;
    p.n = m.grid.n;
    for (int a = 0; a < 3; ++a) p.periodic[a] = d.periodic(a);
    p.kappa_tr = Field<double>(d.local(), 1, 1, 0.0);
    p.sigma_a = Field<double>(d.local(), 0, 1, 0.0);
    const double sigma_tr = o.sigma_t * (1.0 - o.albedo * o.g);
    // rho's ghost layer is exchanged (0 outside a non-periodic domain), so kappa_tr's is too.
    for_each_cell(p.kappa_tr.allocated(), [&](int i, int j, int k) {
        p.kappa_tr(i, j, k) = m.rho(i, j, k) * sigma_tr;
    });
    for_each_cell(d.local(), [&](int i, int j, int k) {
        p.sigma_a(i, j, k) = m.rho(i, j, k) * o.sigma_t * (1.0 - o.albedo);
    });
    // Per unit density and unit E0 T': Q0' = q0, Q1' = g' q0 w, G = g' q0 w / sigma_tr.
    const double q0 = o.sigma_t * o.albedo * (1.0 - s.f) / (4.0 * std::numbers::pi);
    const size_t nl = light.lights.size();
    const FirstScatterMeans means = [&] {
        std::optional<ScopedTimer> timer;  // under "sources" when the model calls
        if (report) timer.emplace(*report, "first_scatter_bound");
        std::vector<bool> lit(nl, false);  // in some right-hand side
        for (const std::vector<double>& weight : group.rhs_weights)
            for (size_t l = 0; l < nl; ++l) lit[l] = lit[l] || weight[l] != 0.0;
        return FirstScatterMeans(light, d, m.rho, s.sigma_t, m.grid.h, lit);
    }();
    if (report) {
        std::vector<std::string> names;
        for (const BandUse& use : group.bands) names.push_back(m.bands[static_cast<size_t>(use.band)].name);
        means.report(fmt::format("{}", fmt::join(names, ", ")), *report);
    }
    const Box& dom = d.global();
    const auto outside = [&](int a, int v) { return !d.periodic(a) && (v < dom.lo[a] || v >= dom.hi[a]); };
    // Whether a full cell has a Marshak face: only such a cell has a sheet to split.
    const auto on_surface = [&](int i, int j, int k) {
        for (int a = 0; a < 3; ++a)
            for (int side : {-1, 1}) {
                int nb[3] = {i, j, k};
                nb[a] += side;
                if (outside(a, nb[a]) || p.kappa_tr(nb[0], nb[1], nb[2]) <= 0.0) return true;
            }
        return false;
    };
    // The right-hand sides' fields on the full cells' bounding box (DiffusionProblem::rhs_within).
    if (!group.rhs_weights.empty()) p.rhs_within = find_solve_region(d, p, 0).box;
    const Box own = p.rhs_within.empty() ? d.local() : d.local().intersect(p.rhs_within);
    for (const std::vector<double>& weight : group.rhs_weights) {
        Field<double> Q0(own, 0, 1, 0.0), G(own, 1, 3, 0.0), escape(own, 0, 3, 0.0);
        for_each_cell(own, [&](int i, int j, int k) {
            if (p.kappa_tr(i, j, k) <= 0.0) return;
            const double rho = m.rho(i, j, k), h = m.grid.h;
            const SheetCell cell{s.sigma_t * rho * h, 1.0 / (3.0 * p.kappa_tr(i, j, k)), p.sigma_a(i, j, k), h};
            const bool surface = on_surface(i, j, k);
            double e = 0.0, left = 0.0;  // the lights' sum of weight x <T'>, and of what leaves
            Vec3 ew, left_flux;
            for (size_t l = 0; l < nl; ++l) {
                if (weight[l] == 0.0) continue;
                // The cell's mean of the (delta-scaled) T: the finite-volume source of the cell.
                const double et = weight[l] * means(static_cast<int>(l), i, j, k);
                e += et;
                ew += light.lights[l].w * et;
                if (!surface || !(et > 0.0)) continue;
                // The faces the light enters by: T' arriving through each Marshak one.
                const Vec3& w = light.lights[l].w;
                std::array<double, 3> t_in;
                for (int a = 0; a < 3; ++a)
                    t_in[a] = light.transmittance_beyond(d, m.rho, static_cast<int>(l), s.sigma_t, i, j, k, a);
                const std::array<double, 3> out =
                    sheet_escape(cell, w, t_in, weight[l] * means.scale(static_cast<int>(l)), et);
                for (int a = 0; a < 3; ++a) {
                    left += et * out[a];
                    left_flux[a] += (w[a] > 0.0 ? -1.0 : 1.0) * et * out[a];
                }
            }
            double emitted = 0.0;  // W/m³ at unit strengths x weights (kappa_tr > 0: the cell has density)
            for (size_t t = 0; t < sources.size(); ++t)
                if (weight[nl + t] != 0.0 && sources[t].cells.contains(i, j, k)) emitted += weight[nl + t];
            Q0(i, j, k) = rho * q0 * (e - left) + emitted / (4.0 * std::numbers::pi);
            for (int c = 0; c < 3; ++c) {
                G(i, j, k, c) = s.g * q0 * ew[c] / sigma_tr;
                escape(i, j, k, c) = rho * q0 * left_flux[c] * h;
            }
        });
        exchange_rhs_halo(p, G, d);
        p.Q0.push_back(std::move(Q0));
        p.G.push_back(std::move(G));
        p.escape_flux.push_back(std::move(escape));
    }
    return p;
}

void add_forward_peak(const Decomposition& d, const Medium& m, const LightTransport& light, const BandGroup& group,
                      bool delta_scaling, std::vector<Field<double>>& fluence, std::vector<Field<double>>& flux) {
    const BandOptics& o = group.optics;
    const DeltaScaledOptics s = delta_scale(o.sigma_t, o.albedo, o.g, delta_scaling);
    if (!(s.f > 0.0)) return;
    std::vector<LightTransport::PeakTarget> targets;
    for (const BandUse& use : group.bands) {
        const auto b = static_cast<size_t>(use.band);
        LightTransport::PeakTarget& t = targets.emplace_back();
        for (const DirectionalLight& L : light.lights) t.e0.push_back(band_value(L.E0, use.band));
        t.fluence = &fluence[b];
        t.flux = &flux[b];
    }
    light.add_forward_peak(d, m.rho, o.sigma_t, s.sigma_t, m.grid.h, d.local(), targets);
}

}  // namespace nimbus::diffusion
