#include "src/render/view_volume.h"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "src/core/error.h"
#include "src/physics/lights.h"
#include "src/render/march.h"
#include "src/render/source_kernel.h"
#include "src/scene/emission.h"

namespace nimbus {
namespace {

// Whether f holds values on every cell of `need` (owned box + ghost layer).
bool covers(const Field<double>& f, const Box& need, int ncomp = 1) {
    return f.allocated().intersect(need) == need && f.ncomp() == ncomp;
}

void check_inputs(const RenderInputs& in, const Box& need) {
    const RenderMode mode = in.scene.render.mode;
    const int nb = in.medium.nbands();
    if (!covers(in.medium.rho, need))
        throw Error("render: medium.rho must cover the rank's box plus 1 ghost layer");
    if (mode == RenderMode::single_unshadowed || mode == RenderMode::scattering) {
        for (const auto& l : in.light.lights)
            if (l.E0.size() != 1 && static_cast<int>(l.E0.size()) != nb)
                throw Error(fmt::format("render: light '{}' has {} irradiance values for {} bands",
                                        l.name, l.E0.size(), nb));
    }
    if (mode == RenderMode::scattering) {
        if (in.light.tau_rho.size() != in.light.lights.size())
            throw Error(fmt::format("render: mode 'scattering' needs tau_rho for each of the {} "
                                    "light terms, got {}", in.light.lights.size(), in.light.tau_rho.size()));
        for (const auto& f : in.light.tau_rho)
            if (!covers(f, need)) throw Error("render: tau_rho must cover the rank's box plus 1 ghost layer");
        const auto& df = in.diffuse;
        if (!df.fluence.empty()) {
            if (static_cast<int>(df.fluence.size()) != nb)
                throw Error(fmt::format("render: diffuse fluence has {} bands, the medium {}",
                                        df.fluence.size(), nb));
            for (const auto& f : df.fluence)
                if (!covers(f, need)) throw Error("render: diffuse fluence must cover the rank's box plus 1 ghost layer");
        }
        if (!df.flux.empty()) {
            if (df.flux.size() != df.fluence.size())
                throw Error("render: diffuse flux needs one field per band, like the fluence");
            for (const auto& f : df.flux)
                if (!covers(f, need, 3)) throw Error("render: diffuse flux must have 3 components on the rank's box plus 1 ghost layer");
        }
    }
}

}  // namespace

void build_occupancy(ViewVolume& v) {
    const int bs = 1 << ViewVolume::kBlockShift;
    for (int a = 0; a < 3; ++a) v.nblocks[a] = (v.owned.size(a) + bs - 1) / bs;
    v.occupied.assign(static_cast<size_t>(v.nblocks[0]) * v.nblocks[1] * v.nblocks[2], 0);
    v.occupied_cells = Box{v.owned.hi, v.owned.lo};  // empty; grows below
    const Box all = v.data.allocated();
    const int nc = v.data.ncomp();
    const float* rho = v.data.data();
    for (int bk = 0; bk < v.nblocks[2]; ++bk)
        for (int bj = 0; bj < v.nblocks[1]; ++bj)
            for (int bi = 0; bi < v.nblocks[0]; ++bi) {
                const Int3 b{bi, bj, bk};
                Box cells;
                for (int a = 0; a < 3; ++a) {
                    cells.lo[a] = v.owned.lo[a] + b[a] * bs;
                    cells.hi[a] = std::min(cells.lo[a] + bs, v.owned.hi[a]);
                }
                const Box apron = cells.grown(1).intersect(all);
                bool any = false;
                for (int k = apron.lo[2]; k < apron.hi[2] && !any; ++k)
                    for (int j = apron.lo[1]; j < apron.hi[1] && !any; ++j) {
                        const float* row = rho + v.data.index(apron.lo[0], j, k);
                        for (int i = 0; i < apron.size(0); ++i)
                            if (row[static_cast<std::ptrdiff_t>(i) * nc] > 0.0f) { any = true; break; }
                    }
                v.occupied[static_cast<size_t>((bk * v.nblocks[1] + bj) * v.nblocks[0] + bi)] = any;
                if (!any) continue;
                for (int a = 0; a < 3; ++a) {
                    v.occupied_cells.lo[a] = std::min(v.occupied_cells.lo[a], cells.lo[a]);
                    v.occupied_cells.hi[a] = std::max(v.occupied_cells.hi[a], cells.hi[a]);
                }
            }
    if (v.occupied_cells.lo[0] >= v.occupied_cells.hi[0]) v.occupied_cells = Box{};
}

ViewVolume build_view_volume(const RenderInputs& in, const Decomposition& d, const Vec3& camera) {
    const Medium& m = in.medium;
    const RenderSpec& rs = in.scene.render;
    const int nb = m.nbands();
    const Box need = d.local().grown(1);
    check_inputs(in, need);

    ViewVolume v;
    v.grid = m.grid;
    v.owned = d.local();
    v.nbands = nb;
    for (const auto& band : m.bands) v.sigma_t.push_back(band.sigma_t);
    const bool emits = rs.mode == RenderMode::emission || rs.mode == RenderMode::emission_absorption;
    const bool scatters = rs.mode == RenderMode::single_unshadowed || rs.mode == RenderMode::scattering;
    const bool shadows = rs.mode == RenderMode::scattering;
    const bool diffuse = shadows && !in.diffuse.fluence.empty();
    const bool flux = diffuse && !in.diffuse.flux.empty();
    const auto& lights = in.light.lights;
    // The layout (header comment): with shadowed lights [rho, Jd.. | A.. | ln T..], each group
    // on a 4-float boundary with 3 bands (the march's vector width).
    v.split_lights = shadows && !lights.empty();
    const int group = nb == 3 ? 4 : nb;
    v.a_offset = v.split_lights ? (nb == 3 ? 4 : 1 + nb) : 0;
    v.log_t_offset = v.split_lights ? v.a_offset + group : 0;
    v.data = Field<float>(d.local(), 1, v.split_lights ? v.log_t_offset + group : 1 + nb, 0.0f);
    v.radiance_bound.assign(static_cast<size_t>(nb) + 1, 0.0);  // + the flag "some J < 0"
    const double kappa_floor = 1.0 / norm(m.grid.extent());
    // ln T below the march's floor (e^-87 of the light is nothing) is stored as the floor: -inf
    // would turn the trilinear weights' products into NaN.
    constexpr double kLogTFloor = kMinLogT;
    std::vector<double> J(static_cast<size_t>(nb)), A(static_cast<size_t>(nb)), W(static_cast<size_t>(nb));
    // The scene's volume sources ([[sources]], emission.h) add their isotropic radiance
    // q_b = power_b / 4π to J in the physical (scattering) modes.
    const std::vector<VolumeSource> sources = scatters ? volume_sources(in.scene) : std::vector<VolumeSource>{};
    std::vector<bool> same_g(static_cast<size_t>(nb), false), same_sigma(static_cast<size_t>(nb), false);
    for (size_t b = 1; b < static_cast<size_t>(nb); ++b) {
        same_g[b] = m.bands[b].g == m.bands[b - 1].g;
        same_sigma[b] = m.bands[b].sigma_t == m.bands[b - 1].sigma_t;
    }

    // A ghost cell across a periodic face is the cell it wraps to: its source cell (the
    // sources' boxes are in domain cells 0..n-1).
    const Int3 n = d.global().hi;
    auto wrap = [&](int a, int c) { return d.periodic(a) ? (c % n[a] + n[a]) % n[a] : c; };

    // With split lights, the empty cells whose ln T a sample can weigh: those next to a cell
    // with medium (a trilinear stencil without medium has A = 0). The rest keep 0 and cost
    // nothing (most of a cloud's domain).
    std::vector<std::uint8_t> near_medium;
    if (v.split_lights) {
        near_medium.assign(static_cast<size_t>(need.cells()), 0);
        const Int3 sz{need.size(0), need.size(1), need.size(2)};
        for_each_cell(need, [&](int i, int j, int k) {
            if (!(m.rho(i, j, k) > 0.0)) return;
            const Box around = Box{{i, j, k}, {i + 1, j + 1, k + 1}}.grown(1).intersect(need);
            for_each_cell(around, [&](int a, int b, int c) {
                near_medium[(static_cast<size_t>(c - need.lo[2]) * sz[1] + (b - need.lo[1])) * sz[0] +
                            (a - need.lo[0])] = 1;
            });
        });
    }
    auto is_near_medium = [&](int i, int j, int k) {
        return near_medium[(static_cast<size_t>(k - need.lo[2]) * need.size(1) + (j - need.lo[1])) * need.size(0) +
                           (i - need.lo[0])] != 0;
    };

    for_each_cell(need, [&](int i, int j, int k) {
        const double rho = m.rho(i, j, k);
        const Int3 src_cell{wrap(0, i), wrap(1, j), wrap(2, k)};
        float* cell = &v.data(i, j, k);
        cell[0] = static_cast<float>(rho);
        // J = 0 where there is no medium; ln T is wanted there too (the march interpolates it
        // toward the medium's cells).
        if (!(rho > 0.0 || (v.split_lights && is_near_medium(i, j, k))) || !(emits || scatters)) return;
        Vec3 w_out{0, 0, 1};
        if (scatters) {
            const Vec3 to_cam = camera - m.grid.center(i, j, k);
            if (norm(to_cam) > 0) w_out = normalized(to_cam);
        }
        if (emits) {
            for (int b = 0; b < nb; ++b)
                J[static_cast<size_t>(b)] = emission_source(band_value(rs.emission_color, b), rho * v.sigma_t[static_cast<size_t>(b)]);
        } else {
            // Radiance scattered toward the camera per unit sigma_s: J_b = Σ_l E0 T p(mu) and,
            // without shadows, W_b = Σ_l E0 p(mu). Bands sharing g (or sigma_t) with the
            // previous band reuse its phase value (or transmittance).
            std::fill(J.begin(), J.end(), 0.0);
            std::fill(W.begin(), W.end(), 0.0);
            for (size_t l = 0; l < lights.size(); ++l) {
                const double tau = shadows ? in.light.tau_rho[l](i, j, k) : 0.0;
                double p = 0.0, T = 1.0;
                for (int b = 0; b < nb; ++b) {
                    const BandOptics& o = m.bands[static_cast<size_t>(b)];
                    if (b == 0 || !same_g[static_cast<size_t>(b)]) p = hg_phase(o.g, dot(lights[l].w, w_out));
                    if (shadows && (b == 0 || !same_sigma[static_cast<size_t>(b)])) T = std::exp(-o.sigma_t * tau);
                    J[static_cast<size_t>(b)] += band_value(lights[l].E0, b) * T * p;  // E0 T p(mu)
                    W[static_cast<size_t>(b)] += band_value(lights[l].E0, b) * p;
                }
            }
            if (v.split_lights) {
                // ln T_b = ln(J_b / W_b) and A_b = kappa a W_b, so that A_b T_b = kappa a J_b at
                // the centre; the lights leave J (Jd below).
                for (int b = 0; b < nb; ++b) {
                    const BandOptics& o = m.bands[static_cast<size_t>(b)];
                    const size_t bb = static_cast<size_t>(b);
                    const double T = W[bb] > 0 ? J[bb] / W[bb] : 1.0;
                    const double log_t = T > 0 ? std::clamp(std::log(T), kLogTFloor, 0.0) : kLogTFloor;
                    cell[v.log_t_offset + b] = static_cast<float>(log_t);
                    A[bb] = rho * o.sigma_t * o.albedo * W[bb];
                    cell[v.a_offset + b] = static_cast<float>(A[bb]);
                    J[bb] = 0.0;
                }
                if (!(rho > 0.0)) return;
            }
            for (int b = 0; b < nb; ++b) {
                const BandOptics& o = m.bands[static_cast<size_t>(b)];
                const size_t bb = static_cast<size_t>(b);
                if (diffuse) {
                    Vec3 F;
                    if (flux) {
                        const Field<double>& f = in.diffuse.flux[bb];
                        F = {f(i, j, k, 0), f(i, j, k, 1), f(i, j, k, 2)};
                    }
                    J[bb] += diffuse_inscatter(in.diffuse.fluence[bb](i, j, k), o.g, flux, F, w_out, in.diffuse.closure);
                }
                J[bb] *= rho * o.sigma_t * o.albedo;
                if (!sources.empty()) J[bb] += emission_radiance(emitted_power(sources, m.rho, b, i, j, k, src_cell));
            }
        }
        for (int b = 0; b < nb; ++b) {
            const size_t bb = static_cast<size_t>(b);
            const double Jmax = std::abs(J[bb]) + (v.split_lights ? A[bb] : 0.0);
            if (!(Jmax <= std::numeric_limits<float>::max()))
                throw Error(fmt::format("render: the view source J = {:.3g} W/(m³ sr) of band {} at cell ({}, {}, {}) "
                                        "is beyond float32 (3.4e38): lower render.emission_color, the lights or "
                                        "the sources' power (or the density)",
                                        Jmax, m.bands[bb].name, i, j, k));
            cell[1 + b] = static_cast<float>(J[bb]);
            // The largest |J| / max(kappa, 1/L) the march can see (the stored floats; march.h):
            // with split lights J = Jd + A T <= |Jd| + A, as T <= 1.
            const double Jf = std::abs(cell[1 + b]) + (v.split_lights ? cell[v.a_offset + b] : 0.0f);
            const double kappa = static_cast<double>(cell[0]) * v.sigma_t[bb];
            double& S = v.radiance_bound[bb];
            S = std::max(S, Jf / std::max(kappa, kappa_floor));
            if (cell[1 + b] < 0) v.radiance_bound.back() = 1.0;
        }
    });
    // Ghosts beyond a non-periodic face repeat the face cell (clamp to edge). The march stops at
    // the domain's face, so a trilinear fade toward a vacuum ghost would only remove the outer
    // half cell's depth (a quarter of it, kappa h / 8 per face crossed: 13% more light through a
    // kappa h = 1 layer lying on the ground), where a fade inside the domain only moves it.
    for_each_cell(need, [&](int i, int j, int k) {
        Int3 c{i, j, k};
        bool outside = false;
        for (int a = 0; a < 3; ++a)
            if (!d.periodic(a) && (c[a] < 0 || c[a] >= n[a])) c[a] = std::clamp(c[a], 0, n[a] - 1), outside = true;
        if (outside) std::copy_n(&v.data(c[0], c[1], c[2]), v.data.ncomp(), &v.data(i, j, k));
    });
    build_occupancy(v);
    return v;
}

void finish_radiance_bound(ViewVolume& v, const std::vector<double>& sky, const std::vector<double>& ground_bound,
                           const Decomposition& d, const std::vector<double>& path) {
    const int nb = v.nbands;
    MPI_Allreduce(MPI_IN_PLACE, v.radiance_bound.data(), nb + 1, MPI_DOUBLE, MPI_MAX, d.comm());
    const double k = (v.radiance_bound.back() > 0 ? 4.0 : 2.0) + (path.empty() ? 0.0 : 1.0);
    v.radiance_bound.pop_back();
    for (int b = 0; b < nb; ++b) {
        const auto bb = static_cast<size_t>(b);
        const double cells = v.radiance_bound[bb] + (path.empty() ? 0.0 : path[bb]);
        v.radiance_bound[bb] = k * std::max({cells, std::abs(sky[bb]), ground_bound[bb]});
    }
}

}  // namespace nimbus
