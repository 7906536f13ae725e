#include "solvers/lpm/angular.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "src/physics/phase.h"

namespace nimbus::lpm {

double face_solid_angle(double x1, double x2, double y1, double y2) {
    auto G = [](double x, double y) { return std::atan(x * y / std::sqrt(1.0 + x * x + y * y)); };
    return G(x2, y2) - G(x1, y2) - G(x2, y1) + G(x1, y1);
}

Vec3 face_direction(int f, double tu, double tv) {
    const int a = face_axis(f);
    Vec3 w;
    w[a] = face_sign(f);
    w[u_axis(a)] = tu;
    w[v_axis(a)] = tv;
    return normalized(w);
}

Angular::Angular(int p, int k) : p_(p), k_(k) {
    const int nb = map_bins();
    dir_.resize(static_cast<size_t>(nb));
    mean_.resize(static_cast<size_t>(nb));
    omega_.resize(static_cast<size_t>(nb));
    coarse_of_.resize(static_cast<size_t>(nb));
    coarse_omega_.assign(static_cast<size_t>(coarse_bins()), 0.0);
    const double d = 2.0 / p;
    constexpr int kSub = 8;  // quadrature of the mean direction over a map bin
    for (int f = 0; f < 6; ++f)
        for (int iv = 0; iv < p; ++iv)
            for (int iu = 0; iu < p; ++iu) {
                const int n = f * p * p + iv * p + iu;
                const double u0 = -1.0 + iu * d, v0 = -1.0 + iv * d;
                dir_[static_cast<size_t>(n)] = face_direction(f, tangent(iu), tangent(iv));
                omega_[static_cast<size_t>(n)] = face_solid_angle(u0, u0 + d, v0, v0 + d);
                Vec3 sum;
                for (int b = 0; b < kSub; ++b)
                    for (int a = 0; a < kSub; ++a) {
                        const double x1 = u0 + a * d / kSub, y1 = v0 + b * d / kSub;
                        const double w = face_solid_angle(x1, x1 + d / kSub, y1, y1 + d / kSub);
                        sum += w * face_direction(f, x1 + 0.5 * d / kSub, y1 + 0.5 * d / kSub);
                    }
                mean_[static_cast<size_t>(n)] = sum / omega_[static_cast<size_t>(n)];
                const int r = p / k;
                const int m = f * k * k + (iv / r) * k + iu / r;
                coarse_of_[static_cast<size_t>(n)] = m;
            }
    const double dc = 2.0 / k;
    for (int f = 0; f < 6; ++f)
        for (int jv = 0; jv < k; ++jv)
            for (int ju = 0; ju < k; ++ju)
                coarse_omega_[static_cast<size_t>(f * k * k + jv * k + ju)] =
                    face_solid_angle(-1.0 + ju * dc, -1.0 + (ju + 1) * dc, -1.0 + jv * dc, -1.0 + (jv + 1) * dc);
}

namespace {

// Adaptive quadrature of HG over a face rectangle. A square is a 2 x 2 Gauss rule scaled to its
// exact solid angle once its angular radius is at most kLobeFraction x max(its angle to the
// lobe's peak, 1 - |g|) -- HG varies on that scale -- and at most kMaxRadius; else it splits in
// four. The gnomonic map shrinks distances, so the tangent half-diagonal bounds the angular
// radius. Near the peak the squares shrink geometrically: the cost grows like log(1/(1-|g|)),
// where a uniform grid fine enough for the lobe grows like (1-|g|)^-2 (tens of seconds and
// hundreds of MiB at g = 0.99, unbounded as |g| -> 1).
constexpr double kLobeFraction = 0.2;
constexpr double kMaxRadius = 0.12;  // rad
constexpr int kMaxDepth = 40;

struct Lobe {
    double g;
    Vec3 w;     // direction of the incident light
    Vec3 peak;  // w for forward scattering, -w for backward
    double width;
};

double integrate_square(const Lobe& lobe, int f, double x1, double x2, double y1, double y2, int depth) {
    const double radius = 0.5 * std::hypot(x2 - x1, y2 - y1);
    const Vec3 c = face_direction(f, 0.5 * (x1 + x2), 0.5 * (y1 + y2));
    const double to_peak = 2.0 * std::asin(std::min(1.0, 0.5 * norm(c - lobe.peak)));
    if (depth >= kMaxDepth || radius <= std::min(kMaxRadius, kLobeFraction * std::max(to_peak, lobe.width))) {
        // 2 x 2 Gauss-Legendre in (u, v) with the gnomonic Jacobian (1 + u² + v²)^{-3/2},
        // weights rescaled to the square's exact solid angle (exact for a constant).
        constexpr double kGauss = 0.28867513459481287;  // 1 / (2 sqrt 3)
        const double xm = 0.5 * (x1 + x2), ym = 0.5 * (y1 + y2), hx = (x2 - x1) * kGauss * 2.0, hy = (y2 - y1) * kGauss * 2.0;
        double sum_j = 0.0, sum_jp = 0.0;
        for (const double su : {-0.5, 0.5})
            for (const double sv : {-0.5, 0.5}) {
                const double u = xm + su * hx, v = ym + sv * hy;
                const double r2 = 1.0 + u * u + v * v;
                const double jac = 1.0 / (r2 * std::sqrt(r2));
                sum_j += jac;
                sum_jp += jac * hg_phase(lobe.g, dot(lobe.w, face_direction(f, u, v)));
            }
        return face_solid_angle(x1, x2, y1, y2) * sum_jp / sum_j;
    }
    const double xm = 0.5 * (x1 + x2), ym = 0.5 * (y1 + y2);
    return integrate_square(lobe, f, x1, xm, y1, ym, depth + 1) + integrate_square(lobe, f, xm, x2, y1, ym, depth + 1) +
           integrate_square(lobe, f, x1, xm, ym, y2, depth + 1) + integrate_square(lobe, f, xm, x2, ym, y2, depth + 1);
}

}  // namespace

double hg_over_face_rectangle(double g, const Vec3& w, int f, double x1, double x2, double y1, double y2) {
    const Lobe lobe{g, w, g >= 0.0 ? w : -w, 1.0 - std::abs(g)};
    return integrate_square(lobe, f, x1, x2, y1, y2, 0);
}

std::vector<double> Angular::hg_over_coarse_bins(double g, const Vec3& w) const {
    std::vector<double> b(static_cast<size_t>(coarse_bins()));
    const double dc = 2.0 / k_;
    for (int f = 0; f < 6; ++f)
        for (int jv = 0; jv < k_; ++jv)
            for (int ju = 0; ju < k_; ++ju) {
                const double x1 = -1.0 + ju * dc, y1 = -1.0 + jv * dc;
                b[static_cast<size_t>(f * k_ * k_ + jv * k_ + ju)] = hg_over_face_rectangle(g, w, f, x1, x1 + dc, y1, y1 + dc);
            }
    return b;
}

const std::vector<double>& Angular::form_factors(double g) const {
    auto it = form_factors_.find(g);
    if (it == form_factors_.end()) it = form_factors_.emplace(g, compute_form_factors(g)).first;
    return it->second;
}

const std::vector<double>& Angular::beam_factors(double g, const Vec3& w) const {
    const std::array<double, 4> key{g, w.x, w.y, w.z};
    auto it = beam_factors_.find(key);
    if (it == beam_factors_.end()) it = beam_factors_.emplace(key, compute_beam_factors(g, w)).first;
    return it->second;
}

std::vector<double> Angular::compute_form_factors(double g) const {
    const int nm = coarse_bins(), nb = map_bins();
    std::vector<double> P(static_cast<size_t>(nb * nm), 0.0);
    if (g == 0.0) {
        for (int n = 0; n < nb; ++n)
            for (int m = 0; m < nm; ++m)
                P[static_cast<size_t>(n * nm + m)] = coarse_omega_[static_cast<size_t>(m)] / (4.0 * std::numbers::pi);
    } else {
        // A map bin's row averages the scattered distribution over sub x sub directions in
        // the bin, enough to resolve how a lobe narrower than the bin straddles coarse bins.
        const double lobe = std::min(0.125, 0.5 * (1.0 - std::abs(g)));
        const int sub = std::clamp(static_cast<int>(std::ceil((2.0 / p_) / (4.0 * lobe))), 2, 8);
        const double d = 2.0 / p_, ds = d / sub;
        std::vector<double> row(static_cast<size_t>(nm));
        // Rows of face 0 by quadrature; the other faces by symmetry (below).
        for (int n = 0; n < p_ * p_; ++n) {
            const int f = n / (p_ * p_), iv = (n / p_) % p_, iu = n % p_;
            std::fill(row.begin(), row.end(), 0.0);
            for (int b = 0; b < sub; ++b)
                for (int a = 0; a < sub; ++a) {
                    const double x1 = -1.0 + iu * d + a * ds, y1 = -1.0 + iv * d + b * ds;
                    const double w1 = face_solid_angle(x1, x1 + ds, y1, y1 + ds);
                    const std::vector<double> into = hg_over_coarse_bins(g, face_direction(f, x1 + 0.5 * ds, y1 + 0.5 * ds));
                    for (int m = 0; m < nm; ++m) row[static_cast<size_t>(m)] += w1 * into[static_cast<size_t>(m)];
                }
            double sum = 0.0;
            for (double v : row) sum += v;
            for (int m = 0; m < nm; ++m) P[static_cast<size_t>(n * nm + m)] = row[static_cast<size_t>(m)] / sum;
        }
        // The axis permutation with signs T_f(x) = (s x_a, x_u, x_v) maps face f onto face 0
        // bin by bin and coarse bins onto coarse bins; HG depends only on ω·ω', so
        // P^{n_f, m} = P^{n_0, T_f(m)}.
        const double dc = 2.0 / k_;
        for (int f = 1; f < 6; ++f) {
            const int a = face_axis(f), s = face_sign(f);
            std::vector<int> image(static_cast<size_t>(nm));
            for (int m = 0; m < nm; ++m) {
                const int fm = m / (k_ * k_), jv = (m / k_) % k_, ju = m % k_;
                const Vec3 c = face_direction(fm, -1.0 + (ju + 0.5) * dc, -1.0 + (jv + 0.5) * dc);
                image[static_cast<size_t>(m)] = coarse_bin_of(Vec3{s * c[a], c[u_axis(a)], c[v_axis(a)]});
            }
            for (int n = 0; n < p_ * p_; ++n)
                for (int m = 0; m < nm; ++m)
                    P[static_cast<size_t>((f * p_ * p_ + n) * nm + m)] = P[static_cast<size_t>(n * nm + image[static_cast<size_t>(m)])];
        }
    }
    // Rows sum to 1 exactly up to one rounding per entry.
    for (int n = 0; n < nb; ++n) {
        double sum = 0.0;
        for (int m = 0; m < nm; ++m) sum += P[static_cast<size_t>(n * nm + m)];
        for (int m = 0; m < nm; ++m) P[static_cast<size_t>(n * nm + m)] /= sum;
    }
    return P;
}

int Angular::coarse_bin_of(const Vec3& w) const {
    int a = 0;
    for (int ax = 1; ax < 3; ++ax)
        if (std::abs(w[ax]) > std::abs(w[a])) a = ax;
    const int f = 2 * a + (w[a] < 0 ? 1 : 0);
    auto cell = [&](double t) { return std::clamp(static_cast<int>(std::floor((t + 1.0) * 0.5 * k_)), 0, k_ - 1); };
    const double wa = std::abs(w[a]);
    return f * k_ * k_ + cell(w[v_axis(a)] / wa) * k_ + cell(w[u_axis(a)] / wa);
}

std::vector<double> Angular::compute_beam_factors(double g, const Vec3& w) const {
    std::vector<double> b = hg_over_coarse_bins(g, w);
    double sum = 0.0;
    for (double v : b) sum += v;
    for (double& v : b) v /= sum;
    return b;
}

}  // namespace nimbus::lpm
