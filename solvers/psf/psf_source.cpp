#include "solvers/psf/psf_source.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "solvers/light/sun_transmittance.h"
#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/log.h"

namespace nimbus::psf {
namespace {

// Cells thicker than this (optical depths) draw a warning (warn_if_cells_thick).
constexpr double kThickCellTau = 5.0;
constexpr int kMaxComp = 64;   // light volume components (lights x sigma_t groups)
constexpr int kMaxLevels = 24;

int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// The level pair around blur width w and the weight of the upper one (w_0 = 0, w_k = 2^k h for
// k >= 1, pyramid.h).
void level_pair(const LightPyramid& p, double w, int& k0, int& k1, double& f) {
    const int top = p.size() - 1;
    const double h = p.level(0).h;
    k0 = w < 2.0 * h ? 0 : std::min(top, std::ilogb(w / h));
    if (k0 == top) {
        k1 = top;
        f = 0.0;
        return;
    }
    k1 = k0 + 1;
    const double w0 = p.level(k0).width, w1 = p.level(k1).width;
    f = std::clamp((w - w0) / (w1 - w0), 0.0, 1.0);
}

}  // namespace

void check_decomposition(const Decomposition& d) {
    d.require_z_slabs("model psf", "its light pyramid and path-length pass work on z slabs");
    if (d.dims()[2] > 1 && d.thinnest(2) < kLevel0Ghost)
        throw Error(fmt::format("model psf needs at least {} z layers per rank (its light volume has {} ghost "
                                "layers): {} layers on {} ranks leave {}; use at most {} rank{}",
                                kLevel0Ghost, kLevel0Ghost, d.global().size(2), d.size(), d.thinnest(2),
                                std::max(1, d.global().size(2) / kLevel0Ghost),
                                std::max(1, d.global().size(2) / kLevel0Ghost) == 1 ? "" : "s"));
}

void check_light_volumes(int nlights, const std::vector<BandOptics>& bands) {
    std::vector<double> sigma;  // distinct sigma_t: bands sharing it share the light volumes
    for (const BandOptics& o : bands)
        if (std::find(sigma.begin(), sigma.end(), o.sigma_t) == sigma.end()) sigma.push_back(o.sigma_t);
    const int groups = static_cast<int>(sigma.size());
    if (nlights * groups <= kMaxComp) return;
    const std::string terms = groups == 1 ? fmt::format("{} light terms", nlights)
                                          : fmt::format("{} light terms x {} bands of different sigma_t", nlights, groups);
    throw Error(fmt::format("model psf: {} need {} light volumes, more than the {} supported; lower sky.directions{}",
                            terms, nlights * groups, kMaxComp, groups == 1 ? "" : " or give bands equal sigma_t"));
}

namespace {

// The light volume holds the reduced light per cell; where a cell is optically thick the light
// scattered at the medium's surface is blurred through the interior and the fluence comes out
// too bright (README, "Known weaknesses"). Said once, by rank 0. Collective.
void warn_if_cells_thick(const Decomposition& d, const Medium& m) {
    nimbus::warn_if_cells_thick(d, m, "psf", kThickCellTau,
                                "its blur spreads the light scattered at the surface through the interior, so "
                                "fluence_diffuse comes out too bright (total against Monte Carlo: 1.2x at 5, 1.7x at "
                                "10, 3.8x at 50 per cell on a box); refine the grid, or use dom");
}

}  // namespace

PsfSource::PsfSource(const SolveContext& ctx, const PsfOptions& opt)
    : lights_(ctx.light.lights), step_growth_(opt.step_growth) {
    const Medium& m = ctx.medium;
    const Decomposition& d = ctx.decomp;
    // Checked here, before the light pass on the indicator below, so that its generic "the
    // light pass needs slabs" does not blame the user's light pass (which may be exact).
    check_decomposition(d);
    const int nb = m.nbands(), nl = static_cast<int>(lights_.size());
    h_ = m.grid.h;
    // Bands: optics and light-volume groups (bands sharing sigma_t share T).
    std::vector<double> group_sigma;
    for (int b = 0; b < nb; ++b) {
        const BandOptics& o = m.bands[static_cast<size_t>(b)];
        BandPsf bp;
        bp.sigma_s = o.sigma_t * o.albedo;
        bp.a_over_b = o.albedo > 0.0 ? (1.0 - o.albedo) / o.albedo : 0.0;
        bp.theta2 = mean_square_angle(o.g);
        bp.phase = (b > 0 && o.g == m.bands[static_cast<size_t>(b - 1)].g) ? bands_.back().phase : MsPhase(o.g);
        auto it = std::find(group_sigma.begin(), group_sigma.end(), o.sigma_t);
        bp.group = static_cast<int>(it - group_sigma.begin());
        if (it == group_sigma.end()) group_sigma.push_back(o.sigma_t);
        bands_.push_back(std::move(bp));
    }
    ngroups_ = static_cast<int>(group_sigma.size());
    group_sigma_ = group_sigma;
    check_collective(d.comm(), nl > 0, "model psf: PsfSource needs a light term (PsfModel::solve handles none)");
    check_light_volumes(nl, m.bands);  // the same on every rank
    warn_if_cells_thick(d, m);
    check_collective(d.comm(), static_cast<int>(ctx.light.tau_rho.size()) == nl,
                     "model psf: the light pass must provide tau_rho for every light term");

    // Light path length inside the medium: the light pass on the indicator of rho > 0.
    Medium indicator;
    indicator.grid = m.grid;
    indicator.bands = m.bands;
    indicator.rho = Field<double>(d.local(), 1, 1, 0.0);
    for_each_cell(m.rho.allocated(), [&](int i, int j, int k) {
        indicator.rho(i, j, k) = m.rho(i, j, k) > 0.0 ? 1.0 : 0.0;
    });
    Report scratch;
    // The sweep (O(cells)) is accurate enough for a path length; the exact pass costs O(cells n).
    const LightTransport s2 = compute_light_transport(d, indicator, lights_, scratch, {}, LightSpec::Method::sweep);

    // Level 0 of the pyramid: T per light and group; the depths tau_rho_l and s2_l.
    Field<double> level0(d.local(), kLevel0Ghost, nl * ngroups_, 0.0);
    depth_.n = m.grid.n;
    depth_.h = m.grid.h;
    depth_.replicated = d.size() == 1;
    depth_.periodic = {d.periodic(0), d.periodic(1), false};
    for (int p = 0; p < d.size(); ++p) depth_.z_owned.emplace_back(d.box_of(p).lo[2], d.box_of(p).hi[2]);
    depth_.values = Field<float>(d.local(), 1, 2 * nl, 0.0f);
    for_each_cell(d.local().grown(1), [&](int i, int j, int k) {
        for (int l = 0; l < nl; ++l) {
            const double tau = ctx.light.tau_rho[static_cast<size_t>(l)](i, j, k);
            depth_.values(i, j, k, 2 * l) = static_cast<float>(tau);
            depth_.values(i, j, k, 2 * l + 1) = static_cast<float>(s2.tau_rho[static_cast<size_t>(l)](i, j, k) );
            if (!d.local().contains(i, j, k)) continue;
            for (int g = 0; g < ngroups_; ++g)
                level0(i, j, k, l * ngroups_ + g) = std::exp(-group_sigma[static_cast<size_t>(g)] * tau);
        }
    });
    pyramid_ = LightPyramid(std::move(level0), m.grid, d, opt.levels);
    check_collective(d.comm(), pyramid_.size() <= kMaxLevels, "model psf: too many pyramid levels");
}

void PsfSource::prepare(const Box& box, const Decomposition& d) {
    gathered_.clear();
    gathered_.reserve(static_cast<size_t>(pyramid_.size()));
    view_.assign(static_cast<size_t>(pyramid_.size()), nullptr);
    for (int k = 1; k < pyramid_.size(); ++k) {
        const PyramidLevel& lv = pyramid_.level(k);
        if (lv.replicated) {
            view_[static_cast<size_t>(k)] = &lv.values;
            continue;
        }
        const int f = 1 << k;
        gathered_.push_back(gather_layers(lv, floor_div(box.lo[2] - 1, f) - 1, floor_div(box.hi[2] + 1, f) + 2, d.comm()));
        view_[static_cast<size_t>(k)] = &gathered_.back();
    }
    if (depth_.replicated) {
        depth_view_ = &depth_.values;
    } else {
        depth_gathered_ = gather_layers(depth_, box.lo[2] - 2, box.hi[2] + 2, d.comm());
        depth_view_ = &depth_gathered_;
    }
}

// The finest of the scattering bands' spacings at depth tau and path S (a band with sigma_s = 0
// has no H to sample): so the sample points do not depend on the order of the bands, nor on
// bands that do not scatter.
double PsfSource::finest_spacing(double tau, double S) const {
    double w2 = std::numeric_limits<double>::infinity();
    for (const BandPsf& b : bands_)
        if (b.sigma_s > 0.0) w2 = std::min(w2, blur_width_sq(b.theta2, b.sigma_s * tau, S, b.a_over_b));
    return step_growth_ * std::max(2.0 * h_, std::isfinite(w2) ? 2.0 * std::sqrt(w2) : 0.0);
}

double PsfSource::spacing_bound(double tau_view, double s_view) const { return finest_spacing(tau_view, s_view); }

double PsfSource::spacing(const Vec3& x, double tau_view, double s_view) const {
    if (!(step_growth_ > 0.0)) return 0.0;
    float depth[2];
    sample_level(*depth_view_, depth_, pyramid_.origin(), x, depth, 2);
    return finest_spacing(tau_view + std::max(0.0f, depth[0]), s_view + std::max(0.0f, depth[1]));
}

void PsfSource::level_at(int k, const Vec3& x, const float* depth, float* out) const {
    if (k > 0) {
        sample_level(*view_[static_cast<size_t>(k)], pyramid_.level(k), pyramid_.origin(), x, out);
        return;
    }
    const int nl = static_cast<int>(lights_.size());
    for (int l = 0; l < nl; ++l)
        for (int g = 0; g < ngroups_; ++g)
            out[l * ngroups_ + g] = static_cast<float>(std::exp(-group_sigma_[static_cast<size_t>(g)] *
                                                                std::max(0.0f, depth[2 * l])));
}

double PsfSource::lookup(const Vec3& x, double w, int c) const {
    int k0, k1;
    double f;
    level_pair(pyramid_, w, k0, k1, f);
    float depth[2 * kMaxComp], v0[kMaxComp], v1[kMaxComp];
    sample_level(*depth_view_, depth_, pyramid_.origin(), x, depth);
    level_at(k0, x, depth, v0);
    level_at(k1, x, depth, v1);
    return (1.0 - f) * v0[c] + f * v1[c];
}

void PsfSource::sample(const Vec3& x, const Vec3& w_out, double tau_view, double s_view, double* H) const {
    const int nl = static_cast<int>(lights_.size()), nb = static_cast<int>(bands_.size());
    float depth[2 * kMaxComp];
    sample_level(*depth_view_, depth_, pyramid_.origin(), x, depth);
    // Pyramid levels sampled at x on first use.
    float cache[kMaxLevels][kMaxComp];
    bool have[kMaxLevels] = {};
    auto level_value = [&](int k, int c) -> double {
        if (k == 0)  // the raw light volume: exp(-sigma_t tau_rho_l) of this component only
            return std::exp(-group_sigma_[static_cast<size_t>(c % ngroups_)] *
                            std::max(0.0f, depth[2 * (c / ngroups_)]));
        if (!have[k]) {
            level_at(k, x, depth, cache[k]);
            have[k] = true;
        }
        return cache[k][c];
    };
    for (int b = 0; b < nb; ++b) H[b] = 0.0;
    for (int l = 0; l < nl; ++l) {
        const DirectionalLight& light = lights_[static_cast<size_t>(l)];
        const double mu = dot(light.w, w_out);
        const double tau2 = std::max(0.0, static_cast<double>(depth[2 * l]));
        const double S = s_view + std::max(0.0, static_cast<double>(depth[2 * l + 1]));
        double factor = 0.0;
        for (int b = 0; b < nb; ++b) {
            const BandPsf& o = bands_[static_cast<size_t>(b)];
            const bool same = b > 0 && o.group == bands_[static_cast<size_t>(b - 1)].group &&
                              o.sigma_s == bands_[static_cast<size_t>(b - 1)].sigma_s &&
                              o.phase.g() == bands_[static_cast<size_t>(b - 1)].phase.g();
            if (!same) {
                const double lt = o.sigma_s * (tau_view + tau2);
                const double w = std::sqrt(blur_width_sq(o.theta2, lt, S, o.a_over_b));
                int k0, k1;
                double f;
                level_pair(pyramid_, w, k0, k1, f);
                const int c = l * ngroups_ + o.group;
                const double T = (1.0 - f) * level_value(k0, c) + (f > 0.0 ? f * level_value(k1, c) : 0.0);
                factor = T * o.phase.weight_fast(lt, mu);
            }
            H[b] += band_value(light.E0, b) * factor;
        }
    }
}

void PsfSource::radiance_bound(int nbands, double* H) const {
    for (int b = 0; b < nbands; ++b) {
        const BandPsf& o = bands_[static_cast<size_t>(b)];
        double e0 = 0.0;
        for (const DirectionalLight& light : lights_) e0 += band_value(light.E0, b);
        H[b] = e0 * o.phase.max_weight();
    }
}

void PsfSource::fluence(const Medium& m, const Decomposition& d, std::vector<Field<double>>& out) {
    prepare(d.local(), d);
    const int nl = static_cast<int>(lights_.size()), nb = static_cast<int>(bands_.size());
    out.assign(static_cast<size_t>(nb), Field<double>(d.local(), 1, 1, 0.0));
    for_each_cell(d.local(), [&](int i, int j, int k) {
        if (!(m.rho(i, j, k) > 0.0)) return;
        const Vec3 x = m.grid.center(i, j, k);
        float depth[2 * kMaxComp];
        sample_level(*depth_view_, depth_, pyramid_.origin(), x, depth);
        for (int b = 0; b < nb; ++b) {
            const BandPsf& o = bands_[static_cast<size_t>(b)];
            double sum = 0.0;
            for (int l = 0; l < nl; ++l) {
                const double lt = o.sigma_s * std::max(0.0, static_cast<double>(depth[2 * l]));
                const double S = std::max(0.0, static_cast<double>(depth[2 * l + 1]));
                const double w = std::sqrt(blur_width_sq(o.theta2, lt, S, o.a_over_b));
                sum += band_value(lights_[static_cast<size_t>(l)].E0, b) * lookup(x, w, l * ngroups_ + o.group) *
                       o.phase.curved_integral(lt);
            }
            out[static_cast<size_t>(b)](i, j, k) = sum;
        }
    });
    for (auto& f : out) exchange_halo(f, d);
}

}  // namespace nimbus::psf
