#include "solvers/diffusion/sources.h"

#include "src/core/halo.h"

namespace nimbus::diffusion {

DiffusionProblem make_problem(const Decomposition& d, const Medium& m, const LightTransport& light,
                              const BandGroup& group) {
    const BandOptics& o = group.optics;
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
    for (int b : group.rhs_band) {
        Field<double> Q0(d.local(), 0, 1, 0.0), G(d.local(), 1, 3, 0.0);
        for_each_cell(d.local(), [&](int i, int j, int k) {
            if (p.kappa_tr(i, j, k) <= 0.0) return;
            Q0(i, j, k) = light.Q0(m, b, i, j, k);
            const Vec3 q1 = light.Q1(m, b, i, j, k);
            for (int c = 0; c < 3; ++c) G(i, j, k, c) = q1[c] / p.kappa_tr(i, j, k);
        });
        exchange_halo(G, d);
        p.Q0.push_back(std::move(Q0));
        p.G.push_back(std::move(G));
    }
    return p;
}

}  // namespace nimbus::diffusion
