// Henyey-Greenstein Legendre moments with delta-M, real spherical harmonics and the
// discrete-to-moment / moment-to-discrete scattering operator. See angular_moments.h.
#include "src/physics/angular_moments.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "src/core/error.h"

namespace nimbus {

LegendrePhase hg_legendre(double g, int L, bool delta_m) {
    if (!(std::abs(g) < 1))
        throw Error(fmt::format("HG Legendre moments: |g| = {} must be < 1", g));
    if (L < 0) throw Error(fmt::format("HG Legendre moments: order L = {} must be >= 0", L));
    LegendrePhase p;
    // Wiscombe 1977 eq. 7: f = chi_{L+1} = g^{L+1}, the FORWARD peak's weight. A backscattering
    // HG (g < 0) has no forward peak: its chi_l alternate in sign, and g^{L+1} > 0 for odd L
    // would give |chi*_1| > 1 (g = -0.9, L = 3: chi*_1 = -4.5, a scattering operator of norm > 1
    // on which source iteration and DSA diverge). Then f = 0: the plain truncated series.
    p.f = delta_m && g > 0 ? std::pow(g, L + 1) : 0.0;
    p.chi.resize(L + 1);
    for (int l = 0; l <= L; ++l) p.chi[l] = (std::pow(g, l) - p.f) / (1.0 - p.f);
    return p;
}

void legendre_polynomials(int L, double mu, std::vector<double>& P) {
    P.assign(L + 1, 1.0);
    if (L >= 1) P[1] = mu;
    for (int l = 2; l <= L; ++l) P[l] = ((2 * l - 1) * mu * P[l - 1] - (l - 1) * P[l - 2]) / l;
}

double legendre_phase_value(const LegendrePhase& p, double mu) {
    std::vector<double> P;
    const int L = static_cast<int>(p.chi.size()) - 1;
    legendre_polynomials(L, mu, P);
    double s = 0;
    for (int l = 0; l <= L; ++l) s += (2 * l + 1) * p.chi[l] * P[l];
    return s / (4.0 * std::numbers::pi);
}

void real_spherical_harmonics(int L, const Vec3& dir, std::vector<double>& Y) {
    const int nmom = (L + 1) * (L + 1);
    Y.assign(nmom, 0.0);
    const double mu = std::clamp(dir.z, -1.0, 1.0);
    const double s = std::sqrt(std::max(0.0, 1.0 - mu * mu));
    const double phi = std::atan2(dir.y, dir.x);
    // Normalized associated Legendre Pb(l,m) = N_lm P_l^m(mu), no Condon-Shortley phase:
    //   Pb(m,m) = sqrt((2m+1)/(2m)) s Pb(m-1,m-1), Pb(0,0) = 1/sqrt(4π),
    //   Pb(m+1,m) = sqrt(2m+3) mu Pb(m,m),
    //   Pb(l,m) = a (mu Pb(l-1,m) - b Pb(l-2,m)), a = sqrt((4l²-1)/(l²-m²)),
    //   b = sqrt(((l-1)²-m²)/(4(l-1)²-1)).
    std::vector<double> Pb((L + 1) * (L + 1), 0.0);  // index l*(L+1)+m
    auto at = [L](int l, int m) { return l * (L + 1) + m; };
    double pmm = 1.0 / std::sqrt(4.0 * std::numbers::pi);
    for (int m = 0; m <= L; ++m) {
        if (m > 0) pmm *= s * std::sqrt((2.0 * m + 1) / (2.0 * m));
        Pb[at(m, m)] = pmm;
        if (m + 1 <= L) Pb[at(m + 1, m)] = std::sqrt(2.0 * m + 3) * mu * pmm;
        for (int l = m + 2; l <= L; ++l) {
            const double a = std::sqrt((4.0 * l * l - 1) / (double(l) * l - double(m) * m));
            const double b = std::sqrt((double(l - 1) * (l - 1) - double(m) * m) /
                                       (4.0 * (l - 1) * (l - 1) - 1));
            Pb[at(l, m)] = a * (mu * Pb[at(l - 1, m)] - b * Pb[at(l - 2, m)]);
        }
    }
    for (int l = 0; l <= L; ++l) {
        Y[l * l + l] = Pb[at(l, 0)];
        for (int m = 1; m <= l; ++m) {
            const double c = std::sqrt(2.0) * Pb[at(l, m)];
            Y[l * l + l + m] = c * std::cos(m * phi);
            Y[l * l + l - m] = c * std::sin(m * phi);
        }
    }
}

MomentOperator make_moment_operator(const Quadrature& q, int L, bool conservative) {
    if (L < 0) throw Error(fmt::format("moment operator: order L = {} must be >= 0", L));
    MomentOperator op;
    op.L = L;
    op.nmom = (L + 1) * (L + 1);
    op.ndir = q.size();
    op.conservative = conservative;
    op.degree.resize(op.nmom);
    for (int l = 0; l <= L; ++l)
        for (int m = -l; m <= l; ++m) op.degree[l * l + l + m] = l;
    op.m2d.assign(static_cast<std::size_t>(op.ndir) * op.nmom, 0.0);
    std::vector<double> Y;
    for (int n = 0; n < op.ndir; ++n) {
        real_spherical_harmonics(L, q.dir[n], Y);
        std::copy(Y.begin(), Y.end(), op.m2d.begin() + static_cast<std::ptrdiff_t>(n) * op.nmom);
    }
    if (conservative) {
        // Ỹ_k = Y_k - q_k / W for l >= 1: Σ_n w_n Ỹ_k(Ω_n) = 0 exactly.
        double W = 0;
        for (double w : q.weight) W += w;
        for (int k = 1; k < op.nmom; ++k) {
            double qk = 0;
            for (int n = 0; n < op.ndir; ++n)
                qk += q.weight[n] * op.m2d[static_cast<std::size_t>(n) * op.nmom + k];
            for (int n = 0; n < op.ndir; ++n)
                op.m2d[static_cast<std::size_t>(n) * op.nmom + k] -= qk / W;
        }
    }
    op.d2m.assign(static_cast<std::size_t>(op.nmom) * op.ndir, 0.0);
    for (int n = 0; n < op.ndir; ++n)
        for (int k = 0; k < op.nmom; ++k)
            op.d2m[static_cast<std::size_t>(k) * op.ndir + n] =
                q.weight[n] * op.m2d[static_cast<std::size_t>(n) * op.nmom + k];
    return op;
}

double quadrature_moment_error(const Quadrature& q, int L) {
    const int nmom = (L + 1) * (L + 1);
    std::vector<double> sum(nmom, 0.0), Y;
    for (int n = 0; n < q.size(); ++n) {
        real_spherical_harmonics(L, q.dir[n], Y);
        for (int k = 0; k < nmom; ++k) sum[k] += q.weight[n] * Y[k];
    }
    double err = 0;
    for (int k = 1; k < nmom; ++k) err = std::max(err, std::abs(sum[k]));
    return err;
}

void scatter_by_moments(const MomentOperator& op, const LegendrePhase& p,
                        const std::vector<double>& psi, std::vector<double>& S) {
    if (static_cast<int>(psi.size()) != op.ndir)
        throw Error("scatter_by_moments: psi has the wrong number of directions");
    if (static_cast<int>(p.chi.size()) < op.L + 1)
        throw Error("scatter_by_moments: the phase function has fewer moments than the operator");
    std::vector<double> phi(op.nmom, 0.0);
    for (int k = 0; k < op.nmom; ++k) {
        double s = 0;
        for (int n = 0; n < op.ndir; ++n)
            s += op.d2m[static_cast<std::size_t>(k) * op.ndir + n] * psi[n];
        phi[k] = p.chi[op.degree[k]] * s;
    }
    S.assign(op.ndir, 0.0);
    for (int n = 0; n < op.ndir; ++n) {
        double s = 0;
        for (int k = 0; k < op.nmom; ++k)
            s += op.m2d[static_cast<std::size_t>(n) * op.nmom + k] * phi[k];
        S[n] = s;
    }
}

}  // namespace nimbus
