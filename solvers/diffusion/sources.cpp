#include "solvers/diffusion/sources.h"

#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "solvers/diffusion/delta_scaling.h"
#include "src/core/halo.h"

namespace nimbus::diffusion {

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
    for (const std::vector<double>& weight : group.rhs_weights) {
        Field<double> Q0(d.local(), 0, 1, 0.0), G(d.local(), 1, 3, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            if (p.kappa_tr(i, j, k) <= 0.0) return;
            double e = 0.0;
            Vec3 ew;
            for (size_t l = 0; l < nl; ++l) {
                if (weight[l] == 0.0) continue;
                // The cell's mean of the (delta-scaled) T: the finite-volume source of the cell.
                const double et = weight[l] * means(static_cast<int>(l), i, j, k);
                e += et;
                ew += light.lights[l].w * et;
            }
            double emitted = 0.0;  // W/m³ at unit strengths x weights (kappa_tr > 0: the cell has density)
            for (size_t t = 0; t < sources.size(); ++t)
                if (weight[nl + t] != 0.0 && sources[t].cells.contains(i, j, k)) emitted += weight[nl + t];
            Q0(i, j, k) = m.rho(i, j, k) * q0 * e + emitted / (4.0 * std::numbers::pi);
            for (int c = 0; c < 3; ++c) G(i, j, k, c) = s.g * q0 * ew[c] / sigma_tr;
        });
        exchange_halo(G, d);
        p.Q0.push_back(std::move(Q0));
        p.G.push_back(std::move(G));
    }
    return p;
}

bool forward_peak_transmittance(const LightTransport& light, const BandOptics& optics, bool delta_scaling,
                                int i, int j, int k, double* dT) {
    const DeltaScaledOptics s = delta_scale(optics.sigma_t, optics.albedo, optics.g, delta_scaling);
    if (!(s.f > 0.0)) return false;
    for (size_t l = 0; l < light.lights.size(); ++l) {
        // T' - T = e^{-sigma_t' tau} - e^{-sigma_t tau}; exactly 0 where the light is unattenuated
        // (tau = 0: above and beside the medium), which spares both exps in most empty cells.
        const double tau = light.tau_rho[l](i, j, k);
        dT[l] = tau == 0.0 ? 0.0 : std::exp(-s.sigma_t * tau) - std::exp(-optics.sigma_t * tau);
    }
    return true;
}

}  // namespace nimbus::diffusion
