#include "src/physics/lights.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace nimbus {

std::vector<DirectionalLight> make_lights(const Scene& scene) {
    std::vector<DirectionalLight> lights;
    const int nb = scene.nbands();
    if (scene.sun.enabled) {
        DirectionalLight sun{"sun", normalized(scene.sun.direction), {}};
        for (int b = 0; b < nb; ++b) sun.E0.push_back(band_value(scene.sun.irradiance, b));
        lights.push_back(sun);
    }
    // A sky dark in every band adds no terms (each would cost every model a full light pass).
    const bool sky_lit = std::any_of(scene.sky.radiance.begin(), scene.sky.radiance.end(), [](double L) { return L != 0.0; });
    if (sky_lit) {
        // Equal-solid-angle bins: n rings in mu = cos(zenith) in (0, 1] of equal width, each
        // with one bin at a golden-angle azimuth (a spiral), light travelling downward (-z).
        const int n = scene.sky.directions;
        const double omega = 2.0 * std::numbers::pi / n;
        const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
        for (int s = 0; s < n; ++s) {
            const double mu = (s + 0.5) / n;  // cos of zenith of the direction TO the sky
            const double sin_t = std::sqrt(1.0 - mu * mu), phi = golden * s;
            const Vec3 to_sky{sin_t * std::cos(phi), sin_t * std::sin(phi), mu};
            DirectionalLight bin{fmt::format("sky[{}]", s), -to_sky, {}};
            for (int b = 0; b < nb; ++b) bin.E0.push_back(band_value(scene.sky.radiance, b) * omega);
            lights.push_back(bin);
        }
    }
    return lights;
}

}  // namespace nimbus
