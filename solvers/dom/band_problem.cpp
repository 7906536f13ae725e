#include "solvers/dom/band_problem.h"

#include <cmath>

#include "src/physics/lights.h"

namespace nimbus::dom {

BandProblem make_band_optics(const Medium& m, const BandOptics& o, const Box& own, const AngularSet& ang,
                             bool delta_m) {
    BandProblem p;
    p.h = m.grid.h;
    p.phase = hg_legendre(o.g, ang.L, delta_m);
    const double f = p.phase.f, a = o.albedo;
    p.kappa = Field<double>(own, 0, 1, 0.0);
    p.sigma_s = Field<double>(own, 0, 1, 0.0);
    p.sigma_a = Field<double>(own, 0, 1, 0.0);
    p.kappa_tr = Field<double>(own, 0, 1, 0.0);
    p.emission = Field<double>(own, 0, 1, 0.0);
    p.forward_fluence = Field<double>(own, 0, 1, 0.0);
    p.forward_flux = Field<double>(own, 0, 3, 0.0);
    for_each_cell(own, [&](int i, int j, int k) {
        const double kappa = m.rho(i, j, k) * o.sigma_t;
        p.kappa(i, j, k) = delta_m_sigma_t_scale(a, f) * kappa;
        p.sigma_s(i, j, k) = (1.0 - f) * a * kappa;
        p.sigma_a(i, j, k) = (1.0 - a) * kappa;
        p.kappa_tr(i, j, k) = kappa * (1.0 - a * o.g);
    });
    return p;
}

LightTransport without_sky(const LightTransport& lt) {
    LightTransport r;
    for (size_t l = 0; l < lt.lights.size(); ++l) {
        if (lt.lights[l].name.rfind("sky[", 0) == 0) continue;
        r.lights.push_back(lt.lights[l]);
        r.tau_rho.push_back(lt.tau_rho[l]);
    }
    return r;
}

SourceRows source_rows(const BandProblem& p) {
    if (p.nl > 0) return SourceRows(p.kappa.owned(), {&p.sigma_s, &p.emission, &p.amp});
    return SourceRows(p.kappa.owned(), {&p.sigma_s, &p.emission});
}

std::vector<double> moment_chi(const BandProblem& p, const AngularSet& ang) {
    std::vector<double> chi;
    for (int k = 0; k < ang.nmom; ++k) {
        const auto l = static_cast<size_t>(ang.degree[static_cast<size_t>(k)]);
        chi.push_back(l < p.phase.chi.size() ? p.phase.chi[l] : 0.0);
    }
    return chi;
}

void make_source_moments(const BandProblem& p, const std::vector<double>& chi, const SourceRows& rows,
                         const double* phi, double* s, bool with_emission) {
    const size_t nm = chi.size();
    const double y0inv = std::sqrt(4.0 * std::acos(-1.0));  // 1 / Y_00
    const double* ss = p.sigma_s.data();
    const double* em = p.emission.data();
    rows.for_each_cell([&](size_t c, size_t q) {
        for (size_t k = 0; k < nm; ++k) s[q * nm + k] = ss[c] * chi[k] * phi[q * nm + k];
        if (with_emission) s[q * nm] += y0inv * em[c];
    });
}

FirstScatterMeans add_light_sources(BandProblem& p, const Decomposition& d, const Medium& m, const LightTransport& lt,
                                    const BandOptics& o, const std::vector<double>& E0, const AngularSet& ang) {
    std::vector<int> lit;  // the lights of lt this problem carries
    std::vector<bool> carried(lt.lights.size());
    for (size_t l = 0; l < lt.lights.size(); ++l) {
        carried[l] = E0[l] != 0.0;
        if (carried[l]) lit.push_back(static_cast<int>(l));
    }
    const int nl = static_cast<int>(lit.size());
    const Box own = p.kappa.owned();
    const double f = p.phase.f, scale = delta_m_sigma_t_scale(o.albedo, f);
    p.nl = nl;
    p.amp = Field<double>(own, 0, std::max(1, nl), 0.0);
    // Phase values per octant, renormalized over the whole quadrature.
    std::vector<double> norm(static_cast<size_t>(nl), 0.0);
    for (int oc = 0; oc < 8; ++oc) {
        const auto& od = ang.octants[static_cast<size_t>(oc)];
        const int nd = od.size();
        auto& P = p.light_phase[static_cast<size_t>(oc)];
        P.assign(static_cast<size_t>(nl * nd), 0.0);
        for (int l = 0; l < nl; ++l)
            for (int n = 0; n < nd; ++n) {
                const Vec3& w = lt.lights[static_cast<size_t>(lit[static_cast<size_t>(l)])].w;
                const double v = legendre_phase_value(p.phase, dot(od.dir[static_cast<size_t>(n)], w));
                P[static_cast<size_t>(l * nd + n)] = v;
                norm[static_cast<size_t>(l)] += od.weight[static_cast<size_t>(n)] * v;
            }
    }
    for (auto& P : p.light_phase) {
        const size_t nd = nl > 0 ? P.size() / static_cast<size_t>(nl) : 0;
        for (size_t q = 0; q < P.size(); ++q) P[q] /= norm[q / nd];
    }
    const FirstScatterMeans means(lt, d, m.rho, scale * o.sigma_t, m.grid.h, carried);
    for (int l = 0; l < nl; ++l) {
        const int t = lit[static_cast<size_t>(l)];
        const double e0 = E0[static_cast<size_t>(t)];
        // The source integrates over the cell: the cell's mean of the scaled beam's T (only
        // where the cell scatters: 88% of the default cloud's cells do not).
        for_each_cell(own, [&](int i, int j, int k) {
            if (p.sigma_s(i, j, k) != 0.0) p.amp(i, j, k, l) = p.sigma_s(i, j, k) * e0 * means(t, i, j, k);
        });
    }
    // The forward peak: the cell's mean of T' - T, as the fluence is a cell mean.
    if (f > 0.0) {
        LightTransport::PeakTarget target{E0, &p.forward_fluence, &p.forward_flux};
        lt.add_forward_peak(d, m.rho, o.sigma_t, scale * o.sigma_t, m.grid.h, own, {target});
    }
    return means;
}

FirstScatterMeans add_light_sources(BandProblem& p, const Decomposition& d, const Medium& m, const LightTransport& lt,
                                    int b, const AngularSet& ang) {
    std::vector<double> E0;
    for (const DirectionalLight& light : lt.lights) E0.push_back(band_value(light.E0, b));
    return add_light_sources(p, d, m, lt, m.bands[static_cast<size_t>(b)], E0, ang);
}

}  // namespace nimbus::dom
