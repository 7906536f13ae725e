// Quadrature sets on the unit sphere: LQ_N level-symmetric, Gauss-Legendre x Chebyshev product,
// cube-face bins. See quadrature.h for the formulas and sources.
#include "src/physics/quadrature.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "src/core/error.h"

namespace nimbus {
namespace {

constexpr double kPi = std::numbers::pi;

// Least squares min |A x - b| for a small dense A (rows x cols, row-major, rows >= cols, full
// column rank) by Householder QR. A and b are working copies.
std::vector<double> least_squares(std::vector<double> A, std::vector<double> b, int rows,
                                  int cols) {
    for (int k = 0; k < cols; ++k) {
        double s = 0;
        for (int i = k; i < rows; ++i) s += A[i * cols + k] * A[i * cols + k];
        const double alpha = -std::copysign(std::sqrt(s), A[k * cols + k]);
        std::vector<double> v(rows, 0.0);
        for (int i = k; i < rows; ++i) v[i] = A[i * cols + k];
        v[k] -= alpha;
        double vv = 0;
        for (int i = k; i < rows; ++i) vv += v[i] * v[i];
        if (vv == 0) continue;
        for (int j = k; j < cols; ++j) {
            double d = 0;
            for (int i = k; i < rows; ++i) d += v[i] * A[i * cols + j];
            for (int i = k; i < rows; ++i) A[i * cols + j] -= 2 * d / vv * v[i];
        }
        double d = 0;
        for (int i = k; i < rows; ++i) d += v[i] * b[i];
        for (int i = k; i < rows; ++i) b[i] -= 2 * d / vv * v[i];
    }
    std::vector<double> x(cols);
    for (int k = cols - 1; k >= 0; --k) {
        double s = b[k];
        for (int j = k + 1; j < cols; ++j) s -= A[k * cols + j] * x[j];
        x[k] = s / A[k * cols + k];
    }
    return x;
}

// ∫_{octant} x^{2a} y^{2b} z^{2c} dΩ / (π/2): the octant average of an even monomial,
// 2 Γ(a+½) Γ(b+½) Γ(c+½) / Γ(a+b+c+3/2) over the sphere, divided by 4π.
double octant_moment(int a, int b, int c) {
    return 2.0 * std::tgamma(a + 0.5) * std::tgamma(b + 0.5) * std::tgamma(c + 0.5) /
           std::tgamma(a + b + c + 1.5) / (4.0 * kPi);
}

// Solid angle of [0,a] x [0,b] on the plane at unit distance; odd in a and in b.
double rect_solid_angle(double a, double b) {
    return std::atan(a * b / std::sqrt(1.0 + a * a + b * b));
}

// P_n(z) and P_n'(z) by the three-term recurrence (|z| < 1).
void legendre_pn(int n, double z, double& p, double& dp) {
    double p0 = 1, p1 = z;
    for (int l = 2; l <= n; ++l) {
        const double p2 = ((2 * l - 1) * z * p1 - (l - 1) * p0) / l;
        p0 = p1;
        p1 = p2;
    }
    p = p1;
    dp = n * (z * p1 - p0) / (z * z - 1);
}

}  // namespace

double level_symmetric_mu1(int N) {
    // Standard LQ_N values (Lewis & Miller 1984 Table 4-1 to 7 digits; full precision here).
    static constexpr std::array<double, 8> kMu1 = {
        0.577350269189625764509149,  // S2 = 1/sqrt(3)
        0.350021174581540677777041,  // S4
        0.266635401516704720331535,  // S6
        0.218217890235992381266097,  // S8 = 1/sqrt(21)
        0.189321326478010476671494,  // S10
        0.167212652822713264084504,  // S12
        0.151985861461031912404799,  // S14
        0.138956875067780344591732,  // S16
    };
    if (N < 2 || N > 16 || N % 2 != 0)
        throw Error(fmt::format("level-symmetric order S{} unsupported: N must be even, 2..16", N));
    return kMu1[N / 2 - 1];
}

Quadrature level_symmetric(int N) {
    const double mu1 = level_symmetric_mu1(N);
    const int n = N / 2;
    std::vector<double> mu(n);
    for (int i = 0; i < n; ++i)
        mu[i] = N == 2 ? mu1 : std::sqrt(mu1 * mu1 + i * 2.0 * (1.0 - 3.0 * mu1 * mu1) / (N - 2));

    // Octant points (i, j, k), 0-based with i + j + k = n - 1, and their permutation classes.
    std::vector<std::array<int, 3>> pts;
    std::vector<std::array<int, 3>> classes;
    std::vector<int> cls;
    for (int i = 0; i < n; ++i)
        for (int j = 0; i + j < n; ++j) {
            const int k = n - 1 - i - j;
            pts.push_back({i, j, k});
            std::array<int, 3> key{i, j, k};
            std::sort(key.begin(), key.end());
            auto it = std::find(classes.begin(), classes.end(), key);
            if (it == classes.end()) {
                classes.push_back(key);
                it = classes.end() - 1;
            }
            cls.push_back(static_cast<int>(it - classes.begin()));
        }
    const int nc = static_cast<int>(classes.size());

    // Even-moment conditions Σ_octant w x^{2a} y^{2b} z^{2c} = octant_moment(a,b,c),
    // a >= b >= c, 2(a+b+c) <= max(N-2, 0): consistent and of full rank nc for N <= 16.
    const int maxdeg = std::max(N - 2, 0) / 2;
    std::vector<double> A, rhs;
    for (int a = 0; a <= maxdeg; ++a)
        for (int b = 0; b <= a; ++b)
            for (int c = 0; c <= b && a + b + c <= maxdeg; ++c) {
                std::vector<double> row(nc, 0.0);
                for (std::size_t p = 0; p < pts.size(); ++p)
                    row[cls[p]] += std::pow(mu[pts[p][0]], 2 * a) * std::pow(mu[pts[p][1]], 2 * b) *
                                   std::pow(mu[pts[p][2]], 2 * c);
                A.insert(A.end(), row.begin(), row.end());
                rhs.push_back(octant_moment(a, b, c));
            }
    const int rows = static_cast<int>(rhs.size());
    const std::vector<double> w = least_squares(A, rhs, rows, nc);
    for (int r = 0; r < rows; ++r) {
        double s = 0;
        for (int c = 0; c < nc; ++c) s += A[r * nc + c] * w[c];
        if (std::abs(s - rhs[r]) > 1e-12)
            throw Error(fmt::format("level-symmetric S{}: moment conditions not met ({:.2e})", N,
                                    std::abs(s - rhs[r])));
    }
    for (double wc : w)
        if (!(wc > 0)) throw Error(fmt::format("level-symmetric S{}: non-positive weight", N));

    Quadrature q;
    q.name = fmt::format("S{} level-symmetric ({} directions)", N, N * (N + 2));
    // Degree N holds too (it fixes mu_1), except for the standard S12 and S16; odd degrees vanish.
    q.exact_degree = (N == 12 || N == 16) ? N - 1 : N + 1;
    for (int o = 0; o < 8; ++o) {
        const double sx = (o & 1) ? -1.0 : 1.0, sy = (o & 2) ? -1.0 : 1.0,
                     sz = (o & 4) ? -1.0 : 1.0;
        for (std::size_t p = 0; p < pts.size(); ++p) {
            q.dir.push_back({sx * mu[pts[p][0]], sy * mu[pts[p][1]], sz * mu[pts[p][2]]});
            q.weight.push_back(w[cls[p]] * (kPi / 2.0));
        }
    }
    return q;
}

void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
    if (n < 1) throw Error("Gauss-Legendre: need at least 1 point");
    x.assign(n, 0.0);
    w.assign(n, 0.0);
    for (int i = 0; i < (n + 1) / 2; ++i) {
        // Newton on P_n from Tricomi's asymptotic guess for the i-th largest root.
        double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), p = 0, dp = 1;
        for (int it = 0; it < 100; ++it) {
            legendre_pn(n, z, p, dp);
            const double dz = p / dp;
            z -= dz;
            if (std::abs(dz) < 1e-16) break;
        }
        legendre_pn(n, z, p, dp);
        x[n - 1 - i] = z;
        x[i] = -z;
        w[i] = w[n - 1 - i] = 2.0 / ((1 - z * z) * dp * dp);
    }
}

Quadrature product_quadrature(int polar, int azimuthal) {
    if (polar < 2 || polar % 2 != 0)
        throw Error(fmt::format("product quadrature: polar = {} must be even and >= 2", polar));
    if (azimuthal < 4 || azimuthal % 4 != 0)
        throw Error(
            fmt::format("product quadrature: azimuthal = {} must be a multiple of 4 (no direction "
                        "in a coordinate plane)",
                        azimuthal));
    std::vector<double> x, wx;
    gauss_legendre(polar, x, wx);
    Quadrature q;
    q.name = fmt::format("product Gauss-Legendre {} x Chebyshev {} ({} directions)", polar,
                         azimuthal, polar * azimuthal);
    q.exact_degree = std::min(2 * polar - 1, azimuthal - 1);
    for (int i = 0; i < polar; ++i) {
        const double s = std::sqrt(1.0 - x[i] * x[i]);
        for (int j = 0; j < azimuthal; ++j) {
            const double phi = (2 * j + 1) * kPi / azimuthal;
            q.dir.push_back({s * std::cos(phi), s * std::sin(phi), x[i]});
            q.weight.push_back(wx[i] * 2.0 * kPi / azimuthal);
        }
    }
    return q;
}

Quadrature cube_face_bins(int per_edge) {
    if (per_edge < 2 || per_edge % 2 != 0)
        throw Error(
            fmt::format("cube-face bins: per_edge = {} must be even and >= 2 (no direction in a "
                        "coordinate plane)",
                        per_edge));
    Quadrature q;
    q.name = fmt::format("cube-face bins {}x{} per face ({} directions)", per_edge, per_edge,
                         6 * per_edge * per_edge);
    q.exact_degree = 3;  // cubic symmetry: Σ w x² = Σ w y² = Σ w z² = 4π/3; odd degrees vanish
    const double h = 2.0 / per_edge;
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            const double sign = side == 0 ? 1.0 : -1.0;
            for (int i = 0; i < per_edge; ++i)
                for (int j = 0; j < per_edge; ++j) {
                    const double a0 = -1 + i * h, a1 = a0 + h, b0 = -1 + j * h, b1 = b0 + h;
                    Vec3 c;
                    c[axis] = sign;
                    c[(axis + 1) % 3] = 0.5 * (a0 + a1);
                    c[(axis + 2) % 3] = 0.5 * (b0 + b1);
                    q.dir.push_back(normalized(c));
                    q.weight.push_back(rect_solid_angle(a1, b1) - rect_solid_angle(a0, b1) -
                                       rect_solid_angle(a1, b0) + rect_solid_angle(a0, b0));
                }
        }
    return q;
}

Quadrature make_quadrature(const DomOptions& opt) {
    if (opt.quadrature == "level-symmetric") return level_symmetric(opt.order);
    if (opt.quadrature == "product") return product_quadrature(opt.polar, opt.azimuthal);
    if (opt.quadrature == "cube96") return cube_face_bins(4);
    throw Error(
        fmt::format("model.dom.quadrature = '{}': allowed are level-symmetric, product, cube96",
                    opt.quadrature));
}

}  // namespace nimbus
