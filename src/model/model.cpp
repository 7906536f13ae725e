#include "src/model/model.h"

#include <numbers>

#include "src/physics/phase.h"

namespace nimbus {

double LightTransport::fluence_reduced(const Medium& m, int b, int i, int j, int k) const {
    double sum = 0.0;
    for (size_t l = 0; l < lights.size(); ++l)
        sum += lights[l].E0[static_cast<size_t>(b)] * transmittance(static_cast<int>(l), m.bands[b].sigma_t, i, j, k);
    return sum;
}

double LightTransport::Q0(const Medium& m, int b, int i, int j, int k) const {
    const double sigma_s = m.kappa(b, i, j, k) * m.bands[b].albedo;
    return sigma_s * fluence_reduced(m, b, i, j, k) / (4.0 * std::numbers::pi);
}

Vec3 LightTransport::Q1(const Medium& m, int b, int i, int j, int k) const {
    const double sigma_s = m.kappa(b, i, j, k) * m.bands[b].albedo;
    Vec3 sum;
    for (size_t l = 0; l < lights.size(); ++l)
        sum += lights[l].w * (lights[l].E0[static_cast<size_t>(b)] *
                              transmittance(static_cast<int>(l), m.bands[b].sigma_t, i, j, k));
    return sum * (m.bands[b].g * sigma_s / (4.0 * std::numbers::pi));
}

DiffuseSolution zero_solution(const Decomposition& d, int nbands) {
    DiffuseSolution s;
    for (int b = 0; b < nbands; ++b) s.fluence.emplace_back(d.local(), 1, 1, 0.0);
    return s;
}

}  // namespace nimbus
