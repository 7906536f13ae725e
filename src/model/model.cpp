#include "src/model/model.h"

#include <mpi.h>

#include <algorithm>
#include <array>
#include <cassert>

#include <cmath>
#include <limits>

#include "src/core/bounding_box.h"
#include "src/core/log.h"
#include "src/model/forward_peak_kernels.h"
#include "src/physics/phase.h"

namespace nimbus {

namespace {

// log(sinh(x) / x) for x >= 0, without overflow (x up to ~1e300).
double log_sinhc(double x) {
    if (x < 1e-3) return x * x / 6.0;
    return x + std::log1p(-std::exp(-2.0 * x)) - std::log(2.0 * x);
}

// sinh(x) / x for 0 <= x <= ~700: the Taylor series sum x^2n / (2n+1)! below 1/2 (the first
// omitted term, x^16 / 17!, is below 5e-20 there), one exp above (e - 1/e loses at most a factor
// 2.2 of its precision at x = 1/2). About a third of log_sinhc's cost.
double sinhc(double x) {
    if (x < 0.5) {
        const double t = x * x;
        return 1.0 + t * (1.0 / 6 + t * (1.0 / 120 + t * (1.0 / 5040 + t * (1.0 / 362880 + t * (1.0 / 39916800 +
               t * (1.0 / 6227020800 + t * (1.0 / 1307674368000)))))));
    }
    const double e = std::exp(x);
    return 0.5 * (e - 1.0 / e) / x;
}

// ∫_0^U u^n e^{-lambda u} du for n = 0, 1, 2 (U > 0, lambda >= 0): a series below x = lambda U
// = 0.05 (9 terms: the first omitted is below 2e-16 of the sum; the closed forms lose about
// 1e-16 / x³ there), the closed forms above.
std::array<double, 3> exp_moments(double lambda, double U) {
    const double x = lambda * U;
    std::array<double, 3> m{};
    if (x < 0.05) {
        double Un = U;  // U^(n+1)
        for (int n = 0; n < 3; ++n, Un *= U) {
            double term = 1.0, sum = 0.0;  // Σ_k (-x)^k / (k! (n + k + 1))
            for (int k = 0; k < 9; ++k) {
                sum += term / (n + k + 1);
                term *= -x / (k + 1);
            }
            m[static_cast<size_t>(n)] = Un * sum;
        }
        return m;
    }
    const double e = std::exp(-x);
    m[0] = U * -std::expm1(-x) / x;
    m[1] = U * U * (1.0 - e * (1.0 + x)) / (x * x);
    m[2] = U * U * U * (2.0 - e * (2.0 + x * (2.0 + x))) / (x * x * x);
    return m;
}

}  // namespace

double LightTransport::face_mean(const Vec3& w, int a, double lambda) {
    const double wa = std::abs(w[a]), wb = std::abs(w[(a + 1) % 3]), wc = std::abs(w[(a + 2) % 3]);
    const double U = 1.0 / std::max({wa, wb, wc});
    const std::array<double, 3> m = exp_moments(lambda, U);
    return wa * (m[0] - (wb + wc) * m[1] + wb * wc * m[2]);
}

double LightTransport::tau_beyond(const Decomposition& d, const Field<double>& rho, int light, int i, int j, int k,
                                  int a) const {
    const Vec3& w = lights[static_cast<size_t>(light)].w;
    if (w[a] == 0.0) return -1.0;
    int nb[3] = {i, j, k};
    nb[a] += w[a] > 0.0 ? -1 : 1;
    const Box& dom = d.global();
    if (!d.periodic(a) && (nb[a] < dom.lo[a] || nb[a] >= dom.hi[a])) return 0.0;
    if (rho(nb[0], nb[1], nb[2]) > 0.0) return -1.0;
    return tau_rho[static_cast<size_t>(light)](nb[0], nb[1], nb[2]);
}

double LightTransport::transmittance_beyond(const Decomposition& d, const Field<double>& rho, int light,
                                            double sigma_t, int i, int j, int k, int a) const {
    const double t = tau_beyond(d, rho, light, i, j, k, a);
    return t < 0.0 ? -1.0 : std::exp(-sigma_t * t);
}

LightTransport::CellProfile LightTransport::profile(const Decomposition& d, const Field<double>& rho, int light,
                                                    double h, int i, int j, int k) const {
    const Field<double>& tau = tau_rho[static_cast<size_t>(light)];
    // The neighbours at the centre's element ± the fields' strides (both hold the ghost layer):
    // reading each by (i, j, k) cost a third of FirstScatterMeans' pass on the bench cumulus at
    // 64³ (4.1 -> 2.9 ms, 1 rank).
    const double* const tp = &tau(i, j, k);
    const double* const rp = &rho(i, j, k);
    CellProfile p;
    p.w = lights[static_cast<size_t>(light)].w;
    p.tau = *tp;
    p.rho = *rp;
    p.h = h;
    const double tc = p.tau, rc = p.rho;
    const int c[3] = {i, j, k};
    const Box& dom = d.global();
    Vec3 g;  // ∇tau_rho (density / metre)
    for (int a = 0; a < 3; ++a) {
        const std::ptrdiff_t st = tau.stride(a), sr = rho.stride(a);
        // Both neighbours are allocated (the ghost layer); they count only inside the domain.
        const bool in_lo = d.periodic(a) || c[a] > dom.lo[a], in_hi = d.periodic(a) || c[a] + 1 < dom.hi[a];
        const double r_lo = rp[-sr], r_hi = rp[sr];
        const double t_lo = tp[-st], t_hi = tp[st];
        // A neighbour serves if it is in the domain and, when this cell has density, has some too.
        const bool use_lo = in_lo && (rc == 0.0 || r_lo > 0.0), use_hi = in_hi && (rc == 0.0 || r_hi > 0.0);
        double v = 0.0;
        if (use_lo && use_hi) v = (t_hi - t_lo) / (2.0 * h);
        else if (use_hi) v = (t_hi - tc) / h;
        else if (use_lo) v = (tc - t_lo) / h;
        g[a] = v;
        // tau_beyond's answer from the same reads: the face the light enters by is the low one
        // when it travels toward +a.
        if (rc > 0.0 && p.w[a] != 0.0) {
            const bool up_lo = p.w[a] > 0.0;
            const bool inside = up_lo ? in_lo : in_hi;
            const double r_up = up_lo ? r_lo : r_hi, t_up = up_lo ? t_lo : t_hi;
            p.tau_in[static_cast<size_t>(a)] = !inside ? 0.0 : (r_up > 0.0 ? -1.0 : t_up);
        }
    }
    p.gradient = g - p.w * dot(p.w, g) + p.w * rc;  // along the light: d tau_rho / ds = rho, exactly
    return p;
}

double LightTransport::transmittance_mean(const Decomposition& d, const Field<double>& rho, int light,
                                          double sigma_t, double h, int i, int j, int k) const {
    return profile(d, rho, light, h, i, j, k).mean(sigma_t);
}

double LightTransport::forward_peak_in_medium(const Decomposition& d, const Field<double>& rho, int light,
                                              double sigma_t, double sigma_scaled, double h, int i, int j, int k) const {
    CellProfile p = profile(d, rho, light, h, i, j, k);
    // tau_rho >= 0 everywhere: the profile's least value in the cube, tau - (h/2) Σ|g_a|, is
    // held at 0 by scaling the gradient (exact profiles, under a plane face, reach 0 at most). On
    // a staircase surface lit at a grazing angle the neighbours' one-sided differences are no
    // gradient and reached far below 0 (tau 19.5 m at the centre, its least 91 m lower, in a cell
    // of scenes/sphere_ground.toml): T there rose above 1 and T' - T fell to 0.046, where a
    // brute-force mean over the cell's points is 0.165 and the centre's value 0.153; limited 0.148.
    const double spread = 0.5 * h * (std::abs(p.gradient[0]) + std::abs(p.gradient[1]) + std::abs(p.gradient[2]));
    if (spread > p.tau) p.gradient = p.gradient * (p.tau / spread);
    // The profile's difference, with the light of the faces with nothing beyond them as its
    // floor: T' - T >= 0 on every path, so that light's own T' - T is below the cell's. Each mean
    // with its own floor (mean(sigma_scaled) - mean(sigma_t)) was not: a floor can lift the mean
    // of T where it leaves T''s, and on the staircase sphere of scenes/sphere_ground.toml a
    // surface cell's peak fell to 0.62 of the profile's (dom S4's fluence there 0.87 of Monte
    // Carlo's, against 0.98 with the centre's value; 0.97 now). Bounded as <T'> is.
    const double diff = p.profile_mean(sigma_scaled) - p.profile_mean(sigma_t);
    const double lit = p.face_floor(sigma_scaled, diff);
    const double floor = lit > 0.0 ? lit - p.face_floor(sigma_t, 0.0) : 0.0;
    return std::clamp(std::max(diff, floor), 0.0, p.bound(sigma_scaled));
}

void LightTransport::forward_peak_row(const Decomposition& d, const Field<double>& rho, int light, double sigma_t,
                                      double sigma_scaled, double h, int i0, int i1, int j, int k,
                                      double* out) const {
    const Field<double>& tau = tau_rho[static_cast<size_t>(light)];
    assert(tau.stride(0) == 1 && rho.stride(0) == 1);
    const double* const t = &tau(i0, j, k);
    const double* const r = &rho(i0, j, k);
    const int n = i1 - i0;
    empty_cells_peak(n, t, r, sigma_t, sigma_scaled, out);
    for (int q = 0; q < n; ++q)
        if (r[q] > 0.0 && t[q] != 0.0)
            out[q] = forward_peak_in_medium(d, rho, light, sigma_t, sigma_scaled, h, i0 + q, j, k);
}

void LightTransport::add_forward_peak(const Decomposition& d, const Field<double>& rho, double sigma_t,
                                      double sigma_scaled, double h, const Box& cells,
                                      const std::vector<PeakTarget>& targets) const {
    if (cells.empty() || targets.empty()) return;
    for ([[maybe_unused]] const PeakTarget& target : targets)
        assert(target.e0.size() == lights.size() && target.fluence->ncomp() == 1 &&
               (!target.flux || target.flux->ncomp() == 3));
    std::vector<int> shining;  // the lights with a non-zero e0 in some target
    for (size_t l = 0; l < lights.size(); ++l)
        for (const PeakTarget& target : targets)
            if (target.e0[l] != 0.0) {
                shining.push_back(static_cast<int>(l));
                break;
            }
    const auto n = static_cast<size_t>(cells.hi[0] - cells.lo[0]);
    const size_t ns = shining.size();
    std::vector<double> e(targets.size() * ns), w(3 * ns);  // per target the shining lights' e0; their w
    for (size_t s = 0; s < ns; ++s) {
        const auto l = static_cast<size_t>(shining[s]);
        for (size_t t = 0; t < targets.size(); ++t) e[t * ns + s] = targets[t].e0[l];
        for (int c = 0; c < 3; ++c) w[3 * s + static_cast<size_t>(c)] = lights[l].w[c];
    }
    std::vector<double> peak(ns * n);  // per shining light, a row
    std::vector<double> sum(4 * n);    // a target's row: Σ e0 peak, then Σ e0 peak w (x, y, z)
    for (int k = cells.lo[2]; k < cells.hi[2]; ++k)
        for (int j = cells.lo[1]; j < cells.hi[1]; ++j) {
            for (size_t s = 0; s < ns; ++s)
                forward_peak_row(d, rho, shining[s], sigma_t, sigma_scaled, h, cells.lo[0], cells.hi[0], j, k,
                                 &peak[s * n]);
            for (size_t t = 0; t < targets.size(); ++t) {
                std::fill(sum.begin(), sum.end(), 0.0);
                sum_peaks(static_cast<int>(n), static_cast<int>(ns), peak.data(), &e[t * ns], w.data(), sum.data());
                double* const fluence = &(*targets[t].fluence)(cells.lo[0], j, k);
                for (size_t q = 0; q < n; ++q) fluence[q] += sum[q];
                if (!targets[t].flux) continue;
                double* const flux = &(*targets[t].flux)(cells.lo[0], j, k);
                for (size_t q = 0; q < n; ++q)
                    for (size_t c = 0; c < 3; ++c) flux[3 * q + c] += sum[(1 + c) * n + q];
            }
        }
}

double LightTransport::CellProfile::profile_mean(double sigma_t) const {
    double x[3];
    for (int a = 0; a < 3; ++a) x[a] = 0.5 * sigma_t * h * std::abs(gradient[a]);
    const double depth = sigma_t * tau;
    // e^{-sigma_t tc} and the sinhc product are both finite when their exponents are below 600;
    // beyond, the sum of logarithms (e^{-50} x (e^{50}/100) at kappa h = 100 in a thick slab).
    if (depth < 600.0 && x[0] + x[1] + x[2] < 600.0) return std::exp(-depth) * (sinhc(x[0]) * sinhc(x[1]) * sinhc(x[2]));
    double log_mean = -depth;
    for (int a = 0; a < 3; ++a) log_mean += log_sinhc(x[a]);
    return std::exp(std::min(log_mean, 0.0));
}

double LightTransport::CellProfile::face_floor(double sigma_t, double above) const {
    if (!(rho > 0.0)) return 0.0;
    const double lambda = sigma_t * rho * h;
    // face_mean(w, a, lambda) <= min(face_mean(w, a, 0), |w_a| / lambda): the integrals only
    // where the faces could bring more than `above`.
    std::array<double, 3> t_in{};  // T beyond each face the light enters by (0: medium there)
    double most = 0.0;
    for (int a = 0; a < 3; ++a) {
        if (tau_in[static_cast<size_t>(a)] < 0.0) continue;
        const double t = std::exp(-sigma_t * tau_in[static_cast<size_t>(a)]);
        if (t <= 0.0) continue;
        t_in[static_cast<size_t>(a)] = t;
        // face_mean(w, a, 0) in closed form: the share of the cube's volume lit through face a
        const double wa = std::abs(w[a]), wb = std::abs(w[(a + 1) % 3]), wc = std::abs(w[(a + 2) % 3]);
        const double U = 1.0 / std::max({wa, wb, wc});
        most += t * std::min(wa * U * (1.0 - U * ((wb + wc) / 2.0 - U * wb * wc / 3.0)), wa / lambda);
    }
    if (!(most > above)) return 0.0;
    double floor = 0.0;
    for (int a = 0; a < 3; ++a)
        if (t_in[static_cast<size_t>(a)] > 0.0) floor += t_in[static_cast<size_t>(a)] * face_mean(w, a, lambda);
    return floor;
}

double LightTransport::CellProfile::bound(double sigma_t) const {
    // What the cell removes from the beam bounds the mean: each ray through the cell loses
    // T_in (1 - e^{-kappa len}) <= 1, and the rays through a cube cover h² (|w_x| + |w_y| + |w_z|),
    // so kappa h³ <T> <= h² Σ|w_a|, and <T> <= 1. Exact profiles never reach the bound (a cell
    // under a plane boundary: <T> = (1 - e^{-kappa h / |w_a|}) |w_a| / (kappa h)). Where the
    // neighbours' differences are no gradient (a staircase surface: one lit, one deep in shadow),
    // the extrapolated profile went far below tau = 0 at a corner and the "mean" far above 1: on
    // a dense sphere (kappa h = 32) dom's first-scatter source carried 1e6 x the incident power.
    if (!(rho > 0.0)) return 1.0;
    return std::min(1.0, (std::abs(w[0]) + std::abs(w[1]) + std::abs(w[2])) / (sigma_t * rho * h));
}

double LightTransport::CellProfile::mean(double sigma_t) const {
    // The light that enters by the faces with no medium beyond them (an empty cell, T of its
    // centre, or the domain's face, T = 1) is a floor under the mean: the linear profile misses
    // it where the cell's neighbours are lit through other faces (the side of a box under an
    // oblique sun: its cells took <T> 300x too small at kappa h = 20, as the neighbour inside
    // sees the light of the top face).
    const double m = profile_mean(sigma_t);
    return std::min(std::max(m, face_floor(sigma_t, m)), bound(sigma_t));
}

FirstScatterMeans::FirstScatterMeans(const LightTransport& lt, const Decomposition& d, const Field<double>& rho,
                                     double sigma_t, double h, const std::vector<bool>& lit)
    : lt_(lt), d_(d), rho_(rho), sigma_t_(sigma_t), h_(h) {
    const size_t nl = lt.lights.size();
    const Box& dom = d.global();
    const Box own = d.local();
    std::vector<double> sums(2 * nl, 0.0);  // per light: taken, then lost
    const auto used = [&](size_t l) { return lit.empty() || lit[l]; };
    int nused = 0;
    for (size_t l = 0; l < nl; ++l) nused += used(l) ? 1 : 0;
    if (nused > 0 && nused <= kMaxKeptLights) {
        // On the bounding box of this rank's cells with density, the only cells whose means
        // are kept (on the default cloud, 1 rank, 36% of the box: 9 lights' means on the whole
        // box were 42 MB, and the pass 1.5-1.8x slower with 4 KiB pages on this machine, which
        // first touched them).
        kept_ = Field<double>(local_bounding_box(own, [&](int i, int j, int k) { return rho(i, j, k) > 0.0; }), 0,
                              nused, 0.0);
        kept_slot_.assign(nl, -1);
        for (size_t l = 0, slot = 0; l < nl; ++l)
            if (used(l)) kept_slot_[l] = static_cast<int>(slot++);
    }
    for (size_t l = 0; l < nl; ++l) {
        if (!used(l)) continue;
        const Vec3& w = lt.lights[l].w;
        const int light = static_cast<int>(l);
        const int slot = kept_slot_.empty() ? -1 : kept_slot_[l];
        const Field<double>& tau = lt.tau_rho[l];
        double taken = 0.0, lost = 0.0;
        for_each_cell(own, [&](int i, int j, int k) {
            const double r = rho(i, j, k);
            if (!(r > 0.0)) return;
            const double mean = lt.transmittance_mean(d, rho, light, sigma_t, h, i, j, k);
            if (slot >= 0) kept_(i, j, k, slot) = mean;
            taken += sigma_t * r * h * h * h * mean;
        });
        // Each non-periodic face the light enters by has as many cells as the one it leaves by,
        // so in - out is the sum over the leaving face's cells of h² |w_a| (1 - T there): no
        // cancellation where the medium is thin. 1 - T is taken at the darkest of the cell and
        // its eight neighbours in the face (1 where any has density): the centres sample a
        // shadow, and one whose area is not a whole number of cells can cover fewer centres than
        // cells (an opaque cell's 1.75-cell shadow over one centre cut its correct source to
        // 0.57), while a shadow at least a cell wide always covers one.
        for (int a = 0; a < 3; ++a) {
            if (d.periodic(a) || w[a] == 0.0) continue;
            const int layer = w[a] > 0.0 ? dom.hi[a] - 1 : dom.lo[a];
            if (layer < own.lo[a] || layer >= own.hi[a]) continue;  // this rank has no cell on it
            const int b = (a + 1) % 3, c = (a + 2) % 3;
            const auto inside = [&](int axis, int v) {
                return d.periodic(axis) || (v >= dom.lo[axis] && v < dom.hi[axis]);
            };
            for_each_cell(own.with_range(a, layer, layer + 1), [&](int i, int j, int k) {
                double darkest = 0.0;  // the largest tau_rho around, or infinity at density
                for (int db = -1; db <= 1; ++db)
                    for (int dc = -1; dc <= 1; ++dc) {
                        int q[3] = {i, j, k};
                        q[b] += db;
                        q[c] += dc;
                        if (!inside(b, q[b]) || !inside(c, q[c])) continue;
                        if (rho(q[0], q[1], q[2]) > 0.0) darkest = std::numeric_limits<double>::infinity();
                        else darkest = std::max(darkest, tau(q[0], q[1], q[2]));
                    }
                lost += std::abs(w[a]) * h * h * -std::expm1(-sigma_t * darkest);
            });
        }
        sums[l] = taken;
        sums[nl + l] = lost;
    }
    MPI_Allreduce(MPI_IN_PLACE, sums.data(), static_cast<int>(sums.size()), MPI_DOUBLE, MPI_SUM, d.comm());
    for (size_t l = 0; l < nl; ++l) {
        const std::string& name = lt.lights[l].name;
        const double taken = sums[l], lost = sums[nl + l];
        // Above round-off only: a slab that absorbs the whole beam takes exactly what it loses.
        bound_.lights.push_back({name, taken, lost, taken > lost * (1.0 + 1e-9) ? lost / taken : 1.0});
    }
}

void FirstScatterBound::report(const std::string& band, Report& report, bool speak) const {
    for (const Light& l : lights) {
        if (l.scale == 1.0) continue;
        report.values()["first_scatter_bound"][band][l.name] = {{"taken", l.taken}, {"lost", l.lost}};
        if (speak && l.scale < 0.99)
            log::warn("first-scatter source of light '{}' in band '{}': the cells' means of T took {:.3g} W per W/m² "
                      "where the beam loses at most {:.3g} in the domain (tau bends inside cells: grazing light over "
                      "periodic x/y); scaled down by {:.3g}",
                      l.name, band, l.taken, l.lost, l.scale);
    }
}

double LightTransport::fluence_reduced(const Medium& m, int b, int i, int j, int k) const {
    double sum = 0.0;
    for (size_t l = 0; l < lights.size(); ++l)
        sum += lights[l].E0[static_cast<size_t>(b)] * transmittance(static_cast<int>(l), m.bands[b].sigma_t, i, j, k);
    return sum;
}


DiffuseSolution zero_solution(const Decomposition& d, int nbands) {
    DiffuseSolution s;
    for (int b = 0; b < nbands; ++b) s.fluence.emplace_back(d.local(), 1, 1, 0.0);
    return s;
}

std::vector<NegativeFluence> find_negative_fluence(const Decomposition& d, const std::vector<BandOptics>& bands,
                                                   const DiffuseSolution& out, double share) {
    std::vector<NegativeFluence> found;
    for (size_t b = 0; b < bands.size() && b < out.fluence.size(); ++b) {
        const Field<double>& fl = out.fluence[b];
        double ext[2] = {0.0, 0.0};  // -min, max
        for_each_cell(fl.owned(), [&](int i, int j, int k) {
            ext[0] = std::max(ext[0], -fl(i, j, k));
            ext[1] = std::max(ext[1], fl(i, j, k));
        });
        MPI_Allreduce(MPI_IN_PLACE, ext, 2, MPI_DOUBLE, MPI_MAX, d.comm());
        if (ext[0] <= share * ext[1]) continue;
        std::int64_t count = 0;
        for_each_cell(fl.owned(), [&](int i, int j, int k) { count += fl(i, j, k) < -share * ext[1]; });
        MPI_Allreduce(MPI_IN_PLACE, &count, 1, MPI_INT64_T, MPI_SUM, d.comm());
        found.push_back({bands[b].name, count, -ext[0], ext[1]});
    }
    return found;
}

double max_density(const Decomposition& d, const Medium& m) {
    double rho_max = 0.0;
    for_each_cell(d.local(), [&](int i, int j, int k) { rho_max = std::max(rho_max, m.rho(i, j, k)); });
    MPI_Allreduce(MPI_IN_PLACE, &rho_max, 1, MPI_DOUBLE, MPI_MAX, d.comm());
    return rho_max;
}

double max_cell_optical_depth(const Decomposition& d, const Medium& m) {
    double sigma_max = 0.0;
    for (const BandOptics& o : m.bands) sigma_max = std::max(sigma_max, o.sigma_t);
    return max_density(d, m) * sigma_max * m.grid.h;
}

void warn_if_cells_thick(const Decomposition& d, const Medium& m, const std::string& model, double limit,
                         const std::string& consequence) {
    const double depth = max_cell_optical_depth(d, m);
    if (depth > limit && d.rank() == 0)
        log::warn("model {}: cells up to {:.3g} optical depths thick: {}", model, depth, consequence);
}

}  // namespace nimbus
