#include "src/render/ground.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "src/core/error.h"
#include "src/physics/lights.h"

namespace nimbus {

GroundShading::GroundShading(const RenderInputs& in, const Decomposition& d)
    : in_(in), owned_(d.local()) {
    const BackgroundSpec& bg = in.scene.background;
    if (bg.kind != BackgroundSpec::Kind::ground) return;
    const int nb = in.medium.nbands();
    for (int b = 0; b < nb; ++b)
        albedo_.push_back(bg.ground_color.empty() ? bg.ground_albedo : band_value(bg.ground_color, b));
    shadows_ = in.scene.render.mode != RenderMode::single_unshadowed;
    if (shadows_ && in.light.tau_rho.size() != in.light.lights.size())
        throw Error("render: the ground background needs tau_rho from the light pass for every light");
    if (shadows_)
        for (const auto& f : in.light.tau_rho)
            if (f.allocated().intersect(d.local().grown(1)) != d.local().grown(1))
                throw Error("render: tau_rho must cover the rank's box plus 1 ghost layer");
    active_ = d.at_low_boundary(2);
}

bool GroundShading::shade(const Vec3& o, const Vec3& d, double* L) const {
    if (!active_ || !(d.z < 0.0)) return false;
    const Grid& grid = in_.medium.grid;
    const double t = (grid.origin.z - o.z) / d.z;
    if (!(t > 0.0)) return false;
    const double qx = (o.x + t * d.x - grid.origin.x) / grid.h, qy = (o.y + t * d.y - grid.origin.y) / grid.h;
    const int nx = grid.n[0], ny = grid.n[1];
    const int ix = std::clamp(qx < 0 ? -1 : static_cast<int>(std::min(qx, 2.0 * nx)), 0, nx - 1);
    const int iy = std::clamp(qy < 0 ? -1 : static_cast<int>(std::min(qy, 2.0 * ny)), 0, ny - 1);
    if (ix < owned_.lo[0] || ix >= owned_.hi[0] || iy < owned_.lo[1] || iy >= owned_.hi[1]) return false;

    const bool inside = qx >= 0 && qx < nx && qy >= 0 && qy < ny;
    // Bilinear weights between bottom-layer cell centres, clamped into the footprint.
    const double cx = std::clamp(qx - 0.5, 0.0, nx - 1.0), cy = std::clamp(qy - 0.5, 0.0, ny - 1.0);
    const int i0 = static_cast<int>(cx), j0 = static_cast<int>(cy);
    const int i1 = std::min(i0 + 1, nx - 1), j1 = std::min(j0 + 1, ny - 1);
    const double fx = cx - i0, fy = cy - j0;
    const int k = 0;

    const int nb = static_cast<int>(albedo_.size());
    const auto& lights = in_.light.lights;
    for (int b = 0; b < nb; ++b) L[b] = 0.0;
    for (size_t l = 0; l < lights.size(); ++l) {
        const double cos_in = std::max(0.0, -lights[l].w.z);
        if (cos_in == 0.0) continue;
        double tau = 0.0;
        if (shadows_ && inside) {
            const Field<double>& f = in_.light.tau_rho[l];
            tau = (1 - fy) * ((1 - fx) * f(i0, j0, k) + fx * f(i1, j0, k)) +
                  fy * ((1 - fx) * f(i0, j1, k) + fx * f(i1, j1, k));
        }
        for (int b = 0; b < nb; ++b) {
            const double T = tau > 0.0 ? std::exp(-in_.medium.bands[static_cast<size_t>(b)].sigma_t * tau) : 1.0;
            L[b] += band_value(lights[l].E0, b) * cos_in * T;
        }
    }
    for (int b = 0; b < nb; ++b) L[b] *= albedo_[static_cast<size_t>(b)] / std::numbers::pi;
    return true;
}

}  // namespace nimbus
