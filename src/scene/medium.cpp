#include "src/scene/medium.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "src/core/error.h"
#include "src/core/halo.h"

namespace nimbus {

std::vector<Ellipsoid> default_cumulus() {
    // A cumulus heap: a broad base and rising turrets (grid fractions).
    return {
        {{0.50, 0.50, 0.34}, {0.36, 0.30, 0.16}, 1.0},
        {{0.38, 0.46, 0.48}, {0.20, 0.20, 0.20}, 1.0},
        {{0.60, 0.54, 0.52}, {0.22, 0.20, 0.24}, 1.0},
        {{0.50, 0.50, 0.66}, {0.15, 0.15, 0.15}, 1.0},
        {{0.27, 0.56, 0.36}, {0.13, 0.14, 0.12}, 1.0},
        {{0.73, 0.44, 0.38}, {0.14, 0.13, 0.13}, 1.0},
    };
}

ProceduralDensity::ProceduralDensity(const MediumSpec& spec, const Int3& n)
    : spec_(spec), n_(n), ellipsoids_(spec.ellipsoids.empty() ? default_cumulus() : spec.ellipsoids),
      noise_(spec.seed) {}

// Max 1995 §2: a sum of ellipsoidal densities, with 3-D noise perturbing the edges. Each
// ellipsoid contributes density * smoothstep(1 - r²) where r is the ellipsoidal radius; the
// noise displaces r so edges become fractal while the core stays smooth.
double ProceduralDensity::cumulus(double x, double y, double z) const {
    const double s = 1.0 / spec_.noise_scale;
    const double nz = spec_.noise_amplitude > 0 ? spec_.noise_amplitude * noise_.fractal(x * s, y * s, z * s, spec_.noise_octaves) : 0.0;
    double sum = 0.0;
    for (const auto& e : ellipsoids_) {
        const double dx = (x - e.center[0]) / e.radii[0], dy = (y - e.center[1]) / e.radii[1],
                     dz = (z - e.center[2]) / e.radii[2];
        const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
        const double t = std::clamp(1.0 - (r + nz * 0.35 * std::min(r, 1.5)), 0.0, 1.0);
        sum += e.density * t * t * (3.0 - 2.0 * t);
    }
    return std::min(sum, 1.0);
}

double ProceduralDensity::operator()(int i, int j, int k) const {
    const double x = (i + 0.5) / n_[0], y = (j + 0.5) / n_[1], z = (k + 0.5) / n_[2];
    switch (spec_.kind) {
        case MediumSpec::Kind::cumulus:
            return spec_.density * cumulus(x, y, z);
        case MediumSpec::Kind::box:
            return (x >= spec_.box_lo[0] && x < spec_.box_hi[0] && y >= spec_.box_lo[1] &&
                    y < spec_.box_hi[1] && z >= spec_.box_lo[2] && z < spec_.box_hi[2])
                       ? spec_.density : 0.0;
        case MediumSpec::Kind::sphere: {
            const double dx = x - spec_.sphere_center[0], dy = y - spec_.sphere_center[1],
                         dz = z - spec_.sphere_center[2];
            return dx * dx + dy * dy + dz * dz <= spec_.sphere_radius * spec_.sphere_radius
                       ? spec_.density : 0.0;
        }
        default:
            throw Error(fmt::format("medium kind '{}' is not procedural", to_string(spec_.kind)));
    }
}

void fill_procedural_density(const MediumSpec& spec, const Decomposition& d, Field<double>& rho) {
    const ProceduralDensity density(spec, d.global().hi);
    rho.fill(0.0);
    for_each_cell(d.local(), [&](int i, int j, int k) { rho(i, j, k) = density(i, j, k); });
    exchange_halo(rho, d);
}

void check_density(const Field<double>& rho, const Decomposition& d) {
    std::string msg;
    const Box& b = rho.owned();
    for (int k = b.lo[2]; k < b.hi[2] && msg.empty(); ++k)
        for (int j = b.lo[1]; j < b.hi[1] && msg.empty(); ++j)
            for (int i = b.lo[0]; i < b.hi[0]; ++i) {
                const double v = rho(i, j, k);
                // The upper bound: every field is written as float32 (a density of 1e300 passed
                // here and came out as Inf, with NaN in the fields derived from it).
                if (!std::isfinite(v) || v < 0 || v > std::numeric_limits<float>::max()) {
                    msg = fmt::format("density at cell ({}, {}, {}) is {}: densities must be finite, >= 0 and at "
                                      "most {:.3g} (the float32 of the output files)",
                                      i, j, k, v, std::numeric_limits<float>::max());
                    break;
                }
            }
    check_collective(d.comm(), msg.empty(), msg);
}

Grid make_grid(const GridSpec& g) {
    Grid grid;
    grid.n = g.n;
    grid.h = g.h();
    return grid;
}

}  // namespace nimbus
