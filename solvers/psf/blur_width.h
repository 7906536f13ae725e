// Path-integral PSF kernels (Premoze et al. 2004): pure functions, no MPI, no allocation
// after construction. Symbols as in the paper: a absorption and b scattering coefficient (1/m),
// <θ²> the mean square scattering angle, l = ∫ b ds the scattering count of a path, S its length.
//
//   <θ²> = 2π ∫_0^π θ² P(θ) sinθ dθ                                          (eq. 2)
//   w²(S) = ½ (2a/(3S) + 16α/(b S³))⁻¹ = <θ²> b S³ / (16 (1 + S²/(12 ℓ²))),
//           α = 1/(2<θ²>), ℓ² = 1/(a b <θ²>)                                  (eq. 1)
//   w² = <θ²> l S² / (24 (1 + <θ²> (a/b) l² / 12))                           (eq. 18: eq. 1
//        times the 2/3 correction of §3.2 (Tessendorf 1987), with l = b S in a homogeneous medium)
//   P_MS(l, θ) = N(l) P(θ / σ(l)),  σ(l) = sqrt(l / (1 - e^{-l})),  ∫ P_MS dω = 1  (§4.5, TW94)
//   path-curvature weight exp(-α_c Δθ² / l),  α_c = 1 / (4 (1 - g))        (Algorithm 2)
// w is used as the standard deviation per transverse axis of the Gaussian blur.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "src/physics/phase.h"

namespace nimbus::psf {

// Eq. 2 for Henyey-Greenstein g, by the midpoint rule in θ (n intervals).
inline double mean_square_angle(double g, int n = 20000) {
    const double pi = std::numbers::pi, dt = pi / n;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const double t = (i + 0.5) * dt;
        sum += t * t * hg_phase(g, std::cos(t)) * std::sin(t);
    }
    return 2.0 * pi * sum * dt;
}

// Eq. 1: the squared spread width of a collimated beam after distance S (a, b in 1/m).
inline double beam_width_sq_eq1(double a, double b, double theta2, double S) {
    if (!(b > 0.0) || !(S > 0.0)) return 0.0;
    const double alpha = 1.0 / (2.0 * theta2);
    return 0.5 / (2.0 * a / (3.0 * S) + 16.0 * alpha / (b * S * S * S));
}

// Eq. 18 (2/3-corrected): squared blur width for scattering count l, path length S, a/b.
inline double blur_width_sq(double theta2, double l, double S, double a_over_b) {
    if (!(l > 0.0)) return 0.0;
    return theta2 * l * S * S / (24.0 * (1.0 + theta2 * a_over_b * l * l / 12.0));
}

// The multiple-scattering phase function P_MS(l, θ) and its curvature-weighted integral
// G(l) = ∫ exp(-α_c θ²/l) P_MS(l, θ) dω, tabulated on log-spaced l (linear interpolation in
// log l, clamped to [l_min, l_max]).
class MsPhase {
public:
    static constexpr double kLogMin = -6.0, kLogMax = 5.0;  // log10 of the tabulated l range
    static constexpr int kPerDecade = 16;
    static constexpr int kAngles = 257;  // weight table nodes in sin(θ/2)

    MsPhase() = default;
    explicit MsPhase(double g) : g_(g), alpha_c_(1.0 / (4.0 * (1.0 - g))) {
        const int n = static_cast<int>((kLogMax - kLogMin) * kPerDecade) + 1;
        norm_.resize(static_cast<size_t>(n));
        curved_.resize(static_cast<size_t>(n));
        table_.resize(static_cast<size_t>(n * kAngles));
        const int nt = 4000;
        const double pi = std::numbers::pi, dt = pi / nt;
        for (int i = 0; i < n; ++i) {
            const double l = std::pow(10.0, kLogMin + static_cast<double>(i) / kPerDecade);
            const double sig = sigma(l);
            double s0 = 0.0, s1 = 0.0;
            for (int j = 0; j < nt; ++j) {
                const double t = (j + 0.5) * dt;
                s0 += hg_phase(g_, std::cos(t / sig)) * std::sin(t);
            }
            s0 *= dt;
            // The curvature factor is a Gaussian of width sqrt(l / α_c), narrower than dt at small
            // l: its integral runs over [0, 12 widths] (beyond, exp < 1e-62) with nt nodes.
            const double t_end = std::min(pi, 12.0 * std::sqrt(l / alpha_c_)), dt1 = t_end / nt;
            for (int j = 0; j < nt; ++j) {
                const double t = (j + 0.5) * dt1;
                s1 += hg_phase(g_, std::cos(t / sig)) * std::sin(t) * std::exp(-alpha_c_ * t * t / l);
            }
            s1 *= dt1;
            norm_[static_cast<size_t>(i)] = 1.0 / (2.0 * pi * s0);
            curved_[static_cast<size_t>(i)] = s1 / s0;
            for (int j = 0; j < kAngles; ++j) {
                const double v = static_cast<double>(j) / (kAngles - 1), t = 2.0 * std::asin(v);
                table_[static_cast<size_t>(i * kAngles + j)] =
                    std::exp(-alpha_c_ * t * t / l) * norm_[static_cast<size_t>(i)] * hg_phase(g_, std::cos(t / sig));
            }
        }
    }

    double g() const { return g_; }
    static double sigma(double l) { return l < 1e-8 ? 1.0 : std::sqrt(l / -std::expm1(-l)); }
    double normalization(double l) const { return interp(norm_, l); }
    // P_MS(l, θ) (1/sr).
    double operator()(double l, double theta) const {
        return normalization(l) * hg_phase(g_, std::cos(theta / sigma(l)));
    }
    // exp(-α_c θ²/l) P_MS(l, θ): the angular factor of Algorithm 2 (0 for l <= 0 unless θ = 0).
    double weight(double l, double theta) const {
        if (!(l > 0.0)) return 0.0;
        return std::exp(-alpha_c_ * theta * theta / l) * (*this)(l, theta);
    }
    // weight() from a table, as a function of mu = cos θ: bilinear in (log l, sin(θ/2) =
    // sqrt((1 - mu)/2)) (nodes dense near θ = 0, where the curvature factor is narrow at small
    // l; no acos); for the render-time inner loop.
    double weight_fast(double l, double mu) const {
        if (!(l > 0.0)) return 0.0;
        const double x = std::clamp((std::log10(l) - kLogMin) * kPerDecade, 0.0, static_cast<double>(norm_.size() - 1));
        const size_t i = std::min(static_cast<size_t>(x), norm_.size() - 2);
        const double fx = x - static_cast<double>(i);
        const double y = std::sqrt(std::clamp(0.5 * (1.0 - mu), 0.0, 1.0)) * (kAngles - 1);
        const size_t j = std::min(static_cast<size_t>(y), static_cast<size_t>(kAngles - 2));
        const double fy = y - static_cast<double>(j);
        const double* a = &table_[i * kAngles + j];
        const double* b = a + kAngles;
        return below_table(l) * ((1.0 - fx) * ((1.0 - fy) * a[0] + fy * a[1]) + fx * ((1.0 - fy) * b[0] + fy * b[1]));
    }
    // The largest weight_fast() can return: a bilinear interpolation of the table's nodes
    // (all >= 0) times below_table() <= 1 is at most the largest node.
    double max_weight() const { return table_.empty() ? 0.0 : *std::max_element(table_.begin(), table_.end()); }
    // G(l) = ∫ weight(l, θ) dω: 0 at l = 0, and ∝ l below the table (G ~ l (1+g)/(1-g) there), so
    // that a band without scattering (albedo 0: l = 0) and a nearly clear one get (nearly) nothing.
    double curved_integral(double l) const { return l > 0.0 ? below_table(l) * interp(curved_, l) : 0.0; }

private:
    // l / l_min below the tabulated range (the table's first row stands in for its shape), else 1.
    static double below_table(double l) {
        static_assert(kLogMin == -6.0, "l_min below is 10^kLogMin");
        constexpr double l_min = 1e-6;
        return l < l_min ? l / l_min : 1.0;
    }
    static double interp(const std::vector<double>& t, double l) {
        const double x = (std::log10(std::max(l, 1e-300)) - kLogMin) * kPerDecade;
        const double xc = std::clamp(x, 0.0, static_cast<double>(t.size() - 1));
        const size_t i = std::min(static_cast<size_t>(xc), t.size() - 2);
        const double f = xc - static_cast<double>(i);
        return t[i] + f * (t[i + 1] - t[i]);
    }
    double g_ = 0.0, alpha_c_ = 0.25;
    std::vector<double> norm_, curved_, table_;
};

}  // namespace nimbus::psf
