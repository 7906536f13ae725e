#include "src/render/ground.h"

#include <mpi.h>

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
    // Checked collectively: the constructor's MPI_Allreduce below must be reached by every rank
    // or by none (a throw on one rank would leave the others in it).
    std::string problem;
    if (shadows_ && in.light.tau_rho.size() != in.light.lights.size())
        problem = "render: the ground background needs tau_rho from the light pass for every light";
    if (shadows_ && problem.empty())
        for (const auto& f : in.light.tau_rho)
            if (f.allocated().intersect(d.local().grown(1)) != d.local().grown(1))
                problem = "render: tau_rho must cover the rank's box plus 1 ghost layer";
    check_collective(d.comm(), problem.empty(), problem);
    active_ = d.at_low_boundary(2);
    periodic_ = {d.periodic(0), d.periodic(1)};
    if (!shadows_) return;
    // Side faces of every light's tau_rho on every rank: each rank fills the face cells it
    // owns, the sum over ranks assembles them.
    const Int3& n = in.medium.grid.n;
    side_.resize(in.light.lights.size());
    bottom_.resize(in.light.lights.size());
    std::vector<double> all;  // one light's parts, summed over the ranks (a count per light: < 2^31)
    for (size_t l = 0; l < side_.size(); ++l) {
        const Field<double>& tau = in.light.tau_rho[l];
        std::vector<double>& bottom = bottom_[l];
        bottom.assign(static_cast<size_t>(n[0]) * static_cast<size_t>(n[1]), 0.0);
        if (owned_.lo[2] == 0)
            for (int j = owned_.lo[1]; j < owned_.hi[1]; ++j)
                for (int i = owned_.lo[0]; i < owned_.hi[0]; ++i)
                    bottom[static_cast<size_t>(j) * static_cast<size_t>(n[0]) + static_cast<size_t>(i)] = tau(i, j, 0);
        for (int f = 0; f < 4; ++f) {
            const int axis = f / 2, nt = n[1 - axis];
            std::vector<double>& face = side_[l][static_cast<size_t>(f)];
            face.assign(static_cast<size_t>(nt) * static_cast<size_t>(n[2]), 0.0);
            const int c = f % 2 == 0 ? 0 : n[axis] - 1;  // the face's cell layer
            if (c < owned_.lo[axis] || c >= owned_.hi[axis]) continue;
            for (int k = owned_.lo[2]; k < owned_.hi[2]; ++k)
                for (int t = owned_.lo[1 - axis]; t < owned_.hi[1 - axis]; ++t)
                    face[static_cast<size_t>(k) * static_cast<size_t>(nt) + static_cast<size_t>(t)] =
                        axis == 0 ? tau(c, t, k) : tau(t, c, k);
        }
        all.assign(bottom.begin(), bottom.end());
        for (auto& face : side_[l]) all.insert(all.end(), face.begin(), face.end());
        MPI_Allreduce(MPI_IN_PLACE, all.data(), static_cast<int>(all.size()), MPI_DOUBLE, MPI_SUM, d.comm());
        auto at = all.begin();
        for (std::vector<double>* part : {&bottom, &side_[l][0], &side_[l][1], &side_[l][2], &side_[l][3]}) {
            std::copy(at, at + static_cast<std::ptrdiff_t>(part->size()), part->begin());
            at += static_cast<std::ptrdiff_t>(part->size());
        }
    }
    if (!active_) side_.clear(), bottom_.clear();  // only the ranks with a part of the bottom shade
}

namespace {

// Bilinear interpolation of a plane of cell values, v[b * na + a] for cell (a, b), between the
// cells' centres at point (pa, pb) in cell units, clamped to the plane.
double bilinear_centres(const std::vector<double>& v, int na, int nb, double pa, double pb) {
    const double ca = std::clamp(pa - 0.5, 0.0, na - 1.0), cb = std::clamp(pb - 0.5, 0.0, nb - 1.0);
    const int a0 = static_cast<int>(ca), b0 = static_cast<int>(cb);
    const int a1 = std::min(a0 + 1, na - 1), b1 = std::min(b0 + 1, nb - 1);
    const double fa = ca - a0, fb = cb - b0;
    auto at = [&](int a, int b) { return v[static_cast<size_t>(b) * static_cast<size_t>(na) + static_cast<size_t>(a)]; };
    return (1 - fb) * ((1 - fa) * at(a0, b0) + fa * at(a1, b0)) + fb * ((1 - fa) * at(a0, b1) + fa * at(a1, b1));
}

}  // namespace

double GroundShading::ground_tau(size_t l, double qx, double qy) const {
    const int nx = in_.medium.grid.n[0], ny = in_.medium.grid.n[1];
    const Vec3 u = -in_.light.lights[l].w;  // toward the light, u.z > 0
    double px = qx + 0.5 * u.x / u.z, py = qy + 0.5 * u.y / u.z;
    if (periodic_[0]) px -= nx * std::floor(px / nx);
    if (periodic_[1]) py -= ny * std::floor(py / ny);
    auto in_footprint = [&](double x, double y) { return x >= 0.0 && x <= nx && y >= 0.0 && y <= ny; };
    if (!in_footprint(px, py)) return in_footprint(qx, qy) ? 0.0 : side_tau(l, qx, qy);
    return bilinear_centres(bottom_[l], nx, ny, px, py);
}

double GroundShading::side_tau(size_t l, double qx, double qy) const {
    const Int3& n = in_.medium.grid.n;
    const Vec3 u = -in_.light.lights[l].w;  // toward the light, u.z > 0
    // Entry of the ray q + s u (s >= 0, cell units) into [0, nx] x [0, ny] x [0, nz]: the
    // latest entry over x and y (the ray starts at z = 0, below nothing).
    const double q[2] = {qx, qy}, ud[2] = {u.x, u.y};
    double s = 0.0;
    int face = -1;
    for (int a = 0; a < 2; ++a) {
        if (q[a] >= 0.0 && q[a] <= n[a]) continue;
        const bool low = q[a] < 0.0;  // enters through the low face
        if (low ? !(ud[a] > 0.0) : !(ud[a] < 0.0)) return 0.0;  // moving away
        const double sa = ((low ? 0.0 : n[a]) - q[a]) / ud[a];
        if (sa > s) s = sa, face = 2 * a + (low ? 0 : 1);
    }
    if (face < 0) return 0.0;
    const double p[3] = {qx + s * u.x, qy + s * u.y, s * u.z};
    // ground_tau calls this when the ray is outside the footprint at the bottom centres' height:
    // entering below that height, it leaves the footprint again before it (the footprint is
    // convex), crossing only the half cell that is not counted.
    if (p[2] < 0.5) return 0.0;
    const int axis = face / 2, ta = 1 - axis;
    if (p[ta] < 0.0 || p[ta] > n[ta] || p[2] > n[2]) return 0.0;  // misses the domain
    return bilinear_centres(side_[l][static_cast<size_t>(face)], n[ta], n[2], p[ta], p[2]);
}

double GroundShading::radiance_bound(int b) const {
    if (albedo_.empty()) return 0.0;
    double E = 0.0;
    for (const auto& l : in_.light.lights) E += std::abs(band_value(l.E0, b)) * std::max(0.0, -l.w.z);
    return albedo_[static_cast<size_t>(b)] / std::numbers::pi * E;
}

bool GroundShading::shade(const Vec3& o, const Vec3& d, double* L) const {
    if (!active_ || !(d.z < 0.0)) return false;
    const Grid& grid = in_.medium.grid;
    const double t = (grid.origin.z - o.z) / d.z;
    if (!(t > 0.0)) return false;
    double qx = (o.x + t * d.x - grid.origin.x) / grid.h, qy = (o.y + t * d.y - grid.origin.y) / grid.h;
    const int nx = grid.n[0], ny = grid.n[1];
    // Along a periodic axis the medium, and so its shadow, repeats.
    if (periodic_[0]) qx -= nx * std::floor(qx / nx);
    if (periodic_[1]) qy -= ny * std::floor(qy / ny);
    const int ix = std::clamp(qx < 0 ? -1 : static_cast<int>(std::min(qx, 2.0 * nx)), 0, nx - 1);
    const int iy = std::clamp(qy < 0 ? -1 : static_cast<int>(std::min(qy, 2.0 * ny)), 0, ny - 1);
    if (ix < owned_.lo[0] || ix >= owned_.hi[0] || iy < owned_.lo[1] || iy >= owned_.hi[1]) return false;

    const int nb = static_cast<int>(albedo_.size());
    const auto& lights = in_.light.lights;
    for (int b = 0; b < nb; ++b) L[b] = 0.0;
    for (size_t l = 0; l < lights.size(); ++l) {
        const double cos_in = std::max(0.0, -lights[l].w.z);
        if (cos_in == 0.0) continue;
        const double tau = shadows_ ? ground_tau(l, qx, qy) : 0.0;
        for (int b = 0; b < nb; ++b) {
            const double T = tau > 0.0 ? std::exp(-in_.medium.bands[static_cast<size_t>(b)].sigma_t * tau) : 1.0;
            L[b] += band_value(lights[l].E0, b) * cos_in * T;
        }
    }
    for (int b = 0; b < nb; ++b) L[b] *= albedo_[static_cast<size_t>(b)] / std::numbers::pi;
    return true;
}

}  // namespace nimbus
