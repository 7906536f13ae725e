#include "tests/support/slab_reference.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace nimbus::test {

namespace {

// Dense square matrix, row-major.
struct Mat {
    int n = 0;
    std::vector<double> a;
    explicit Mat(int size = 0) : n(size), a(static_cast<size_t>(size) * size, 0.0) {}
    double& operator()(int i, int j) { return a[static_cast<size_t>(i) * n + j]; }
    double operator()(int i, int j) const { return a[static_cast<size_t>(i) * n + j]; }
};

Mat mul(const Mat& x, const Mat& y) {
    Mat r(x.n);
    for (int i = 0; i < x.n; ++i)
        for (int k = 0; k < x.n; ++k) {
            const double v = x(i, k);
            for (int j = 0; j < x.n; ++j) r(i, j) += v * y(k, j);
        }
    return r;
}
Mat add(const Mat& x, const Mat& y) {
    Mat r(x.n);
    for (size_t i = 0; i < r.a.size(); ++i) r.a[i] = x.a[i] + y.a[i];
    return r;
}
std::vector<double> mul(const Mat& x, const std::vector<double>& v) {
    std::vector<double> r(static_cast<size_t>(x.n), 0.0);
    for (int i = 0; i < x.n; ++i)
        for (int j = 0; j < x.n; ++j) r[static_cast<size_t>(i)] += x(i, j) * v[static_cast<size_t>(j)];
    return r;
}
Mat diag_left(const std::vector<double>& d, const Mat& x) {  // diag(d) x
    Mat r = x;
    for (int i = 0; i < x.n; ++i)
        for (int j = 0; j < x.n; ++j) r(i, j) *= d[static_cast<size_t>(i)];
    return r;
}
Mat diag_right(const Mat& x, const std::vector<double>& d) {  // x diag(d)
    Mat r = x;
    for (int i = 0; i < x.n; ++i)
        for (int j = 0; j < x.n; ++j) r(i, j) *= d[static_cast<size_t>(j)];
    return r;
}

// Solves A X = B (B has m columns stored as a matrix or vectors) by LU with partial pivoting.
struct LU {
    Mat lu;
    std::vector<int> piv;
    explicit LU(Mat A) : lu(std::move(A)), piv(static_cast<size_t>(lu.n)) {
        const int n = lu.n;
        for (int k = 0; k < n; ++k) {
            int p = k;
            for (int i = k + 1; i < n; ++i)
                if (std::abs(lu(i, k)) > std::abs(lu(p, k))) p = i;
            piv[static_cast<size_t>(k)] = p;
            if (p != k)
                for (int j = 0; j < n; ++j) std::swap(lu(k, j), lu(p, j));
            if (lu(k, k) == 0.0) throw std::runtime_error("slab reference: singular matrix");
            for (int i = k + 1; i < n; ++i) {
                const double f = lu(i, k) /= lu(k, k);
                for (int j = k + 1; j < n; ++j) lu(i, j) -= f * lu(k, j);
            }
        }
    }
    std::vector<double> solve(std::vector<double> b) const {
        const int n = lu.n;
        for (int k = 0; k < n; ++k) std::swap(b[static_cast<size_t>(k)], b[static_cast<size_t>(piv[static_cast<size_t>(k)])]);
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < i; ++j) b[static_cast<size_t>(i)] -= lu(i, j) * b[static_cast<size_t>(j)];
        for (int i = n - 1; i >= 0; --i) {
            for (int j = i + 1; j < n; ++j) b[static_cast<size_t>(i)] -= lu(i, j) * b[static_cast<size_t>(j)];
            b[static_cast<size_t>(i)] /= lu(i, i);
        }
        return b;
    }
    Mat solve(const Mat& B) const {
        Mat X(B.n);
        std::vector<double> col(static_cast<size_t>(B.n));
        for (int j = 0; j < B.n; ++j) {
            for (int i = 0; i < B.n; ++i) col[static_cast<size_t>(i)] = B(i, j);
            const std::vector<double> x = solve(col);
            for (int i = 0; i < B.n; ++i) X(i, j) = x[static_cast<size_t>(i)];
        }
        return X;
    }
};

// A homogeneous layer: reflection R and diffuse transmission Td (radiance to radiance, the
// same from above and below), direct transmission e_i = exp(-tau/mu_i), and the diffuse
// radiance the beam (unit E0 at the layer's top) sends up out of the top (s_up) and down out
// of the bottom (s_down).
struct Layer {
    Mat R, Td;
    std::vector<double> e, s_up, s_down;
    double tau = 0.0;
};

Layer empty_layer(int n) {
    return {Mat(n), Mat(n), std::vector<double>(static_cast<size_t>(n), 1.0),
            std::vector<double>(static_cast<size_t>(n), 0.0), std::vector<double>(static_cast<size_t>(n), 0.0), 0.0};
}

// Interior radiance at the interface of a (above) and b (below): down D, up U.
void interface_field(const Layer& a, const Layer& b, double mu0, std::vector<double>& D,
                     std::vector<double>& U) {
    const int n = a.R.n;
    const double ea = std::exp(-a.tau / mu0);
    Mat I_RaRb = mul(a.R, b.R);
    for (size_t i = 0; i < I_RaRb.a.size(); ++i) I_RaRb.a[i] = -I_RaRb.a[i];
    for (int i = 0; i < n; ++i) I_RaRb(i, i) += 1.0;
    const LU gamma(I_RaRb);
    std::vector<double> rhs = mul(a.R, b.s_up);
    for (int i = 0; i < n; ++i) rhs[static_cast<size_t>(i)] = a.s_down[static_cast<size_t>(i)] + ea * rhs[static_cast<size_t>(i)];
    D = gamma.solve(rhs);
    U = mul(b.R, D);
    for (int i = 0; i < n; ++i) U[static_cast<size_t>(i)] += ea * b.s_up[static_cast<size_t>(i)];
}

// Adding: layer a on top of layer b (same material).
Layer add_layers(const Layer& a, const Layer& b, double mu0) {
    const int n = a.R.n;
    const double ea = std::exp(-a.tau / mu0);
    Mat I_RaRb = mul(a.R, b.R);
    for (size_t i = 0; i < I_RaRb.a.size(); ++i) I_RaRb.a[i] = -I_RaRb.a[i];
    for (int i = 0; i < n; ++i) I_RaRb(i, i) += 1.0;
    const LU gamma(I_RaRb);
    Mat Ta = a.Td, Tb = b.Td;
    for (int i = 0; i < n; ++i) Ta(i, i) += a.e[static_cast<size_t>(i)], Tb(i, i) += b.e[static_cast<size_t>(i)];

    Layer r;
    r.tau = a.tau + b.tau;
    // R = Ra + Ta Rb Γ Ta
    r.R = add(a.R, mul(Ta, mul(b.R, gamma.solve(Ta))));
    // Td = Eb Tda + Tdb Ea + Tdb Tda + Tb Γ Ra Rb Ta
    Mat td = add(diag_left(b.e, a.Td), diag_right(b.Td, a.e));
    td = add(td, mul(b.Td, a.Td));
    td = add(td, mul(Tb, gamma.solve(mul(a.R, mul(b.R, Ta)))));
    r.Td = td;
    r.e.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) r.e[static_cast<size_t>(i)] = a.e[static_cast<size_t>(i)] * b.e[static_cast<size_t>(i)];
    std::vector<double> D, U;
    interface_field(a, b, mu0, D, U);
    const std::vector<double> up = mul(Ta, U), down = mul(Tb, D);
    r.s_up.resize(static_cast<size_t>(n));
    r.s_down.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
        r.s_up[static_cast<size_t>(i)] = a.s_up[static_cast<size_t>(i)] + up[static_cast<size_t>(i)];
        r.s_down[static_cast<size_t>(i)] = ea * b.s_down[static_cast<size_t>(i)] + down[static_cast<size_t>(i)];
    }
    return r;
}

// ∫_0^Δ exp(-a t) exp(-b (Δ - t)) dt, accurate for a ≈ b.
double both_ends(double a, double b, double delta) {
    const double x = (a - b) * delta;
    if (std::abs(x) < 1e-12) return delta * std::exp(-b * delta);
    return std::exp(-b * delta) * (-std::expm1(-x)) / (a - b);
}
// ∫_0^Δ exp(-s t) dt
double one_end(double s, double delta) { return -std::expm1(-s * delta) / s; }

}  // namespace

void gauss_legendre(int n, double a, double b, std::vector<double>& x, std::vector<double>& w) {
    x.assign(static_cast<size_t>(n), 0.0);
    w.assign(static_cast<size_t>(n), 0.0);
    for (int i = 0; i < n; ++i) {
        double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5)), dp = 0.0;
        for (int it = 0; it < 100; ++it) {
            double p0 = 1.0, p1 = z;
            for (int l = 2; l <= n; ++l) {
                const double p2 = ((2.0 * l - 1.0) * z * p1 - (l - 1.0) * p0) / l;
                p0 = p1;
                p1 = p2;
            }
            dp = n * (z * p1 - p0) / (z * z - 1.0);
            const double dz = p1 / dp;
            z -= dz;
            if (std::abs(dz) < 1e-15) break;
        }
        x[static_cast<size_t>(i)] = 0.5 * (a + b) - 0.5 * (b - a) * z;
        w[static_cast<size_t>(i)] = (b - a) / ((1.0 - z * z) * dp * dp);
    }
}

SlabSolution solve_slab(const SlabProblem& p) {
    if (!(p.tau0 > 0) || !(p.mu0 > 0 && p.mu0 <= 1) || p.albedo < 0 || p.albedo > 1 || std::abs(p.g) >= 1)
        throw std::invalid_argument("slab reference: bad problem");
    SlabSolution s;
    const int L = std::abs(p.g) < 1e-12 ? 0 : static_cast<int>(std::ceil(std::log(1e-8) / std::log(std::abs(p.g))));
    const int N = p.n_half > 0 ? p.n_half : std::max(32, (L + 2) / 2);
    if (L > 2 * N - 1) throw std::invalid_argument("slab reference: too few directions for the Legendre order");
    s.legendre_order = L;
    gauss_legendre(N, 0.0, 1.0, s.mu, s.weight);
    const std::vector<double>& mu = s.mu;
    const std::vector<double>& c = s.weight;

    // Legendre polynomials at ±mu_i and mu0; kernel P(mu, mu') = Σ (2l+1) g^l P_l P_l.
    auto legendre = [&](double x) {
        std::vector<double> P(static_cast<size_t>(L) + 1);
        P[0] = 1.0;
        if (L >= 1) P[1] = x;
        for (int l = 2; l <= L; ++l) P[static_cast<size_t>(l)] = ((2.0 * l - 1.0) * x * P[static_cast<size_t>(l) - 1] - (l - 1.0) * P[static_cast<size_t>(l) - 2]) / l;
        return P;
    };
    std::vector<std::vector<double>> Pl_plus, Pl_minus;
    for (int i = 0; i < N; ++i) Pl_plus.push_back(legendre(mu[static_cast<size_t>(i)])), Pl_minus.push_back(legendre(-mu[static_cast<size_t>(i)]));
    const std::vector<double> Pl0 = legendre(p.mu0);
    auto kernel = [&](const std::vector<double>& x, const std::vector<double>& y) {
        double sum = 0.0, gl = 1.0;
        for (int l = 0; l <= L; ++l, gl *= p.g) sum += (2.0 * l + 1.0) * gl * x[static_cast<size_t>(l)] * y[static_cast<size_t>(l)];
        return sum;
    };

    // Thin layer by exact single scattering.
    int doublings = 0;
    while (p.tau0 / std::ldexp(1.0, doublings) > p.thin) ++doublings;
    const int levels = std::max(1, p.profile_levels);
    if ((levels & (levels - 1)) != 0) throw std::invalid_argument("slab reference: profile_levels must be a power of 2");
    int level_stage = 0;
    while ((1 << level_stage) < levels) ++level_stage;
    doublings = std::max(doublings, level_stage);
    const double delta = p.tau0 / std::ldexp(1.0, doublings);
    const double a = p.albedo;
    Layer thin;
    thin.tau = delta;
    thin.R = Mat(N);
    thin.Td = Mat(N);
    thin.e.resize(static_cast<size_t>(N));
    thin.s_up.resize(static_cast<size_t>(N));
    thin.s_down.resize(static_cast<size_t>(N));
    const double inv_mu0 = 1.0 / p.mu0;
    for (int i = 0; i < N; ++i) {
        const double mi = mu[static_cast<size_t>(i)], ai = 1.0 / mi;
        thin.e[static_cast<size_t>(i)] = std::exp(-delta * ai);
        for (int j = 0; j < N; ++j) {
            const double aj = 1.0 / mu[static_cast<size_t>(j)], cj = c[static_cast<size_t>(j)];
            const double w_pm = 0.5 * a * cj * kernel(Pl_minus[static_cast<size_t>(i)], Pl_plus[static_cast<size_t>(j)]);
            const double w_pp = 0.5 * a * cj * kernel(Pl_plus[static_cast<size_t>(i)], Pl_plus[static_cast<size_t>(j)]);
            thin.R(i, j) = w_pm * ai * one_end(ai + aj, delta);
            thin.Td(i, j) = w_pp * ai * both_ends(aj, ai, delta);
        }
        const double j_up = a / (4.0 * std::numbers::pi) * kernel(Pl_minus[static_cast<size_t>(i)], Pl0);
        const double j_down = a / (4.0 * std::numbers::pi) * kernel(Pl_plus[static_cast<size_t>(i)], Pl0);
        thin.s_up[static_cast<size_t>(i)] = j_up * ai * one_end(ai + inv_mu0, delta);
        thin.s_down[static_cast<size_t>(i)] = j_down * ai * both_ends(inv_mu0, ai, delta);
    }

    // Doubling; keep the layer of thickness tau0 / levels for the profile.
    std::vector<Layer> stages{thin};
    for (int k = 0; k < doublings; ++k) stages.push_back(add_layers(stages.back(), stages.back(), p.mu0));
    const Layer& slab = stages.back();

    double R = 0.0, T = 0.0;
    for (int i = 0; i < N; ++i) {
        R += 2.0 * std::numbers::pi * c[static_cast<size_t>(i)] * mu[static_cast<size_t>(i)] * slab.s_up[static_cast<size_t>(i)];
        T += 2.0 * std::numbers::pi * c[static_cast<size_t>(i)] * mu[static_cast<size_t>(i)] * slab.s_down[static_cast<size_t>(i)];
    }
    s.reflected = R / p.mu0;
    s.transmitted_diffuse = T / p.mu0;
    s.transmitted_direct = std::exp(-p.tau0 / p.mu0);
    s.reflected_radiance = slab.s_up;

    if (p.profile_levels > 0) {
        const Layer& step = stages[static_cast<size_t>(doublings - level_stage)];
        std::vector<Layer> top{empty_layer(N)}, bottom(static_cast<size_t>(levels) + 1, empty_layer(N));
        for (int k = 1; k <= levels; ++k) top.push_back(add_layers(top.back(), step, p.mu0));
        for (int k = levels - 1; k >= 0; --k) bottom[static_cast<size_t>(k)] = add_layers(step, bottom[static_cast<size_t>(k) + 1], p.mu0);
        for (int k = 0; k <= levels; ++k) {
            std::vector<double> D, U;
            interface_field(top[static_cast<size_t>(k)], bottom[static_cast<size_t>(k)], p.mu0, D, U);
            double phi = 0.0;
            for (int i = 0; i < N; ++i) phi += 2.0 * std::numbers::pi * c[static_cast<size_t>(i)] * (D[static_cast<size_t>(i)] + U[static_cast<size_t>(i)]);
            s.tau.push_back(p.tau0 * k / levels);
            s.fluence.push_back(phi);
        }
    }
    return s;
}

}  // namespace nimbus::test
