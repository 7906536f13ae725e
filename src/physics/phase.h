// Henyey-Greenstein phase function, normalized to 1 over the sphere (DESIGN §1):
//   p(mu) = (1 - g²) / (4π (1 + g² - 2 g mu)^{3/2}),  mu = w·w', ∫ p dw' = 1, ∫ p mu dw' = g.
// (Max 1995 eq. 10. Stam 1995 normalizes to 4π instead: never mix the two.)
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include "src/core/vec3.h"

namespace nimbus {

inline double hg_phase(double g, double mu) {
    const double d = 1.0 + g * g - 2.0 * g * mu;
    return (1.0 - g * g) / (4.0 * std::numbers::pi * d * std::sqrt(d));
}

// Samples mu = cos(theta) from HG given a uniform xi in [0, 1). pdf(mu) = 2π p(mu).
[[gnu::always_inline]] inline double hg_sample_mu(double g, double xi) {
    if (std::abs(g) < 1e-4) return 1.0 - 2.0 * xi;
    const double s = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
    return std::clamp((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0);
}

// An orthonormal frame around unit w: returns u, v with (u, v, w) right-handed.
[[gnu::always_inline]] inline void orthonormal_basis(const Vec3& w, Vec3& u, Vec3& v) {
    const double sign = std::copysign(1.0, w.z);
    const double a = -1.0 / (sign + w.z), b = w.x * w.y * a;
    u = {1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x};
    v = {b, sign + w.y * w.y * a, -w.y};
}

// The direction at polar cosine mu and azimuth phi around unit w.
inline Vec3 rotate_direction(const Vec3& w, double mu, double phi) {
    Vec3 u, v;
    orthonormal_basis(w, u, v);
    const double s = std::sqrt(std::max(0.0, 1.0 - mu * mu));
    return u * (s * std::cos(phi)) + v * (s * std::sin(phi)) + w * mu;
}

}  // namespace nimbus
