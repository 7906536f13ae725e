#include "solvers/lpm/tail.h"

#include <algorithm>
#include <numbers>

#include "src/core/halo.h"

#include "solvers/diffusion/solve_diffusion.h"

namespace nimbus::lpm {

double geometric_tail_factor(double remaining, double previous_remaining) {
    if (remaining <= 0.0 || previous_remaining <= 0.0) return 0.0;
    const double rho = std::min(remaining / previous_remaining, kRhoMax);
    return rho / (1.0 - rho);
}

void add_geometric_tail(Field<double>& fluence, const Field<double>& previous, double factor) {
    for_each_cell(fluence.owned(), [&](int i, int j, int k) {
        fluence(i, j, k) += factor * (fluence(i, j, k) - previous(i, j, k));
    });
}

std::vector<Vec3> coarse_mean_directions(const Angular& ang) {
    const int nm = ang.coarse_bins();
    std::vector<Vec3> mean(static_cast<size_t>(nm));
    for (int n = 0; n < ang.map_bins(); ++n)
        mean[static_cast<size_t>(ang.coarse_of(n))] += ang.mean_direction(n) * ang.solid_angle(n);
    for (int c = 0; c < nm; ++c) mean[static_cast<size_t>(c)] = mean[static_cast<size_t>(c)] * (1.0 / ang.coarse_solid_angle(c));
    return mean;
}

DiffusionTail diffusion_tail(const Decomposition& d, const Medium& m, const BandOptics& bo, const Field<double>& U,
                             const Field<double>& kappa, const Angular& ang, Report& report, bool with_current,
                             bool clamp_negative) {
    const int nm = ang.coarse_bins();
    const std::vector<Vec3> mean = coarse_mean_directions(ang);

    diffusion::DiffusionProblem p;
    p.h = m.grid.h;
    p.n = m.grid.n;
    for (int a = 0; a < 3; ++a) p.periodic[a] = d.periodic(a);
    p.kappa_tr = Field<double>(d.local(), 1, 1, 0.0);
    p.sigma_a = Field<double>(d.local(), 0, 1, 0.0);
    const double tr = 1.0 - bo.albedo * bo.g;
    for_each_cell(p.kappa_tr.allocated(), [&](int i, int j, int k) { p.kappa_tr(i, j, k) = kappa(i, j, k) * tr; });
    Field<double> Q0(d.local(), 0, 1, 0.0), G(d.local(), 1, 3, 0.0);
    const double inv4pi = 1.0 / (4.0 * std::numbers::pi);
    for_each_cell(d.local(), [&](int i, int j, int k) {
        p.sigma_a(i, j, k) = kappa(i, j, k) * (1.0 - bo.albedo);
        if (p.kappa_tr(i, j, k) <= 0.0) return;
        double q0 = 0.0;
        Vec3 q1;
        for (int c = 0; c < nm; ++c) {
            const double e = ang.coarse_solid_angle(c) * U(i, j, k, c);
            q0 += e;
            q1 += mean[static_cast<size_t>(c)] * e;
        }
        Q0(i, j, k) = inv4pi * q0;
        if (with_current)
            for (int a = 0; a < 3; ++a) G(i, j, k, a) = inv4pi * q1[a] / p.kappa_tr(i, j, k);
    });
    exchange_halo(G, d);
    p.Q0.push_back(std::move(Q0));
    p.G.push_back(std::move(G));

    DiffusionOptions opt;
    opt.delta_scaling = false;  // not used by solve_diffusion; the source above is unscaled
    opt.clamp_negative = clamp_negative;
    diffusion::DiffusionResult res = diffusion::solve_diffusion(d, p, opt, report);
    DiffusionTail t;
    t.fluence = Field<double>(d.local(), 1, 1, 0.0);
    for_each_cell(t.fluence.allocated(), [&](int i, int j, int k) {
        t.fluence(i, j, k) = 4.0 * std::numbers::pi * res.U[0](i, j, k);
    });
    t.flux = std::move(res.flux[0]);
    t.solver_iterations = res.stats.empty() ? 0 : res.stats[0].iterations;
    t.true_residual = res.stats.empty() ? 0.0 : res.stats[0].true_residual;
    return t;
}

}  // namespace nimbus::lpm
