#include "solvers/lpm/map_sweep.h"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <span>

#include "solvers/lpm/gather_kernel.h"
#include "solvers/lpm/segment_kernel.h"
#include "solvers/sweep/chain.h"
#include "src/core/halo.h"

namespace nimbus::lpm {
namespace {

// Cyclic sweeps along a periodic map axis stop when the map carries less than this fraction
// of its power after the first pass (the rest is counted as `truncated`), or after this many
// passes.
constexpr double kCyclicTolerance = 1e-9;
constexpr long kMaxCyclicPasses = 100;

inline int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// Segments of one ray in one step, for one sub-slot position within its cell: path length
// (m), fluence weight (step fraction x |Ω^n| / R²) and offset of the cell in the padded plane.
struct Pattern {
    int nseg;
    double len[3];
    double w[3];
    int off[3];
};

// Geometry of one map direction in one step: slot shift and R x R sub-slot patterns.
struct StepGeometry {
    int dSu = 0, dSv = 0;
    std::vector<Pattern> pat;  // [rv * R + ru]
};

// Slot position at the start of step `step`: x = 0.5 + step t R = S + phi (slot units).
inline void slot_offset(double t, long step, int R, double& phi, int& dS) {
    const double x0 = 0.5 + static_cast<double>(step) * t * R;
    const double S0 = std::floor(x0);
    phi = x0 - S0;
    dS = static_cast<int>(std::floor(0.5 + static_cast<double>(step + 1) * t * R) - S0);
}

void step_geometry(double tu, double tv, long step, int R, double path_per_step, double wn, int Wu,
                   StepGeometry& g) {
    double phu, phv;
    slot_offset(tu, step, R, phu, g.dSu);
    slot_offset(tv, step, R, phv, g.dSv);
    g.pat.resize(static_cast<size_t>(R * R));
    // Crossing time (step fraction) of the in-plane face toward cell offset dc, or 2 if none.
    auto crossing = [&](int r, double ph, int dS, double t, int& dc) {
        dc = floor_div(r + dS, R);
        if (dc == 0) return 2.0;
        const double edge = dc > 0 ? R : 0.0;
        return std::clamp((edge - (r + ph)) / (t * R), 0.0, 1.0);
    };
    for (int rv = 0; rv < R; ++rv)
        for (int ru = 0; ru < R; ++ru) {
            int du, dv;
            const double cu = crossing(ru, phu, g.dSu, tu, du);
            const double cv = crossing(rv, phv, g.dSv, tv, dv);
            // Events in time order: each moves the ray one cell along its axis.
            double t1 = cu, t2 = cv;
            int o1 = du, o2 = dv * Wu;
            if (t2 < t1) { std::swap(t1, t2); std::swap(o1, o2); }
            Pattern& p = g.pat[static_cast<size_t>(rv * R + ru)];
            double start = 0.0;
            int off = 0;
            p.nseg = 0;
            for (int e = 0; e < 2; ++e) {
                const double te = e == 0 ? t1 : t2;
                if (te > 1.0) break;
                p.len[p.nseg] = (te - start) * path_per_step;
                p.w[p.nseg] = (te - start) * wn;
                p.off[p.nseg] = off;
                ++p.nseg;
                start = te;
                off += e == 0 ? o1 : o2;
            }
            p.len[p.nseg] = (1.0 - start) * path_per_step;
            p.w[p.nseg] = (1.0 - start) * wn;
            p.off[p.nseg] = off;
            ++p.nseg;
        }
}

// Slot layout of one rank's part of a map: NuS x NvS real slots, R overflow rows on each side
// along v (rays handed to the z neighbours), and what lies beyond each edge.
struct SlotLayout {
    int R, NuS, NvS, Wu;
    bool per_u, per_v;  // periodic lateral axes: wrap
    bool nb_lo, nb_hi;  // a rank owns the slots beyond the low/high v edge
    size_t dir_size() const { return static_cast<size_t>(NvS + 2 * R) * NuS; }
    size_t row(int qv) const { return static_cast<size_t>(qv + R) * NuS; }
};

// Propagates every ray of one direction through one step (eq. 4), accumulating the path
// integrals into phi (padded plane) and writing each ray into its next slot in B; the rays
// that leave the domain are summed into esc.
// Radiance sums of the rays that left the domain in one step, per side of the map plane.
struct Escapes {
    double u[2] = {0.0, 0.0};  // low, high side along u
    double v[2] = {0.0, 0.0};
};

// Columns [lo, hi) of a padded row outside which kappa = 0 and Ũ = 0 (lo = hi: all vacuum).
struct MediumSpan {
    int lo = 0, hi = 0;
};

// Advances n rays through one segment each starting at padded (row, col) (segment_kernel.h):
// only the cells inside the row's medium span need the exponential; the rest are vacuum.
// (Cells inside the span may be empty too: advance_rays is exact there as well.)
inline void advance_segment(int n, double* L, int row, int col, int Wu, const MediumSpan* span, const double* K,
                            const double* Us, double* phi, double len, double w) {
    const size_t at = static_cast<size_t>(row) * Wu + col;
    int lo = std::clamp(span[row].lo - col, 0, n), hi = std::clamp(span[row].hi - col, lo, n);
    // Widen the exponential part to whole vectors (exact: at kappa = 0 both kernels agree).
    const int wide = (hi - lo + 3) / 4 * 4;
    if (lo + wide <= n) hi = lo + wide;
    else lo = std::max(0, (hi = n) - wide);
    if (lo > 0) advance_rays_vacuum(lo, L, phi + at, w);
    if (hi > lo) advance_rays(hi - lo, L + lo, K + at + lo, Us + at + lo, phi + at + lo, len, w);
    if (n > hi) advance_rays_vacuum(n - hi, L + hi, phi + at + hi, w);
}

void transport_step(const StepGeometry& g, double tu, double tv, const SlotLayout& s, const MediumSpan* span,
                    const double* K, const double* Us, double* phi, const double* A, double* B, Escapes& esc,
                    std::vector<double>& work) {
    const int R = s.R;
    const int u_lo = s.per_u ? 0 : (tu > 0 ? -R : 0), u_hi = s.per_u ? s.NuS : (tu < 0 ? s.NuS + R : s.NuS);
    const int v_lo = (s.per_v || s.nb_lo || tv <= 0) ? 0 : -R;
    const int v_hi = (s.per_v || s.nb_hi || tv >= 0) ? s.NvS : s.NvS + R;
    const int nU = u_hi - u_lo, ncu = nU / R, cu0 = floor_div(u_lo, R);
    work.resize(static_cast<size_t>(nU + ncu));
    double* Lrow = work.data();
    double* tmp = Lrow + nU;
    // In-range part of the written slots [u_lo + dSu, u_hi + dSu) without wrapping.
    const int w_lo = std::max(0, u_lo + g.dSu), w_hi = std::min(s.NuS, u_hi + g.dSu);
    for (int qv = v_lo; qv < v_hi; ++qv) {
        const bool v_real = qv >= 0 && qv < s.NvS;
        const int cv = floor_div(qv, R);
        const int rv = qv - cv * R;
        int qv2 = qv + g.dSv;
        bool v_out = false;
        if (s.per_v) qv2 = qv2 < 0 ? qv2 + s.NvS : (qv2 >= s.NvS ? qv2 - s.NvS : qv2);
        else v_out = (qv2 < 0 && !s.nb_lo) || (qv2 >= s.NvS && !s.nb_hi);

        if (v_real) {
            // Rays entering from outside the domain along u (slots beyond [0, NuS)) start dark.
            const int c_lo = std::max(0, u_lo) - u_lo, c_hi = std::min(s.NuS, u_hi) - u_lo;
            const double* a = A + s.row(qv);
            std::fill(Lrow, Lrow + c_lo, 0.0);
            std::copy(a + u_lo + c_lo, a + u_lo + c_hi, Lrow + c_lo);
            std::fill(Lrow + c_hi, Lrow + nU, 0.0);
        } else {
            std::fill(Lrow, Lrow + nU, 0.0);
        }
        for (int ru = 0; ru < R; ++ru) {
            const Pattern& p = g.pat[static_cast<size_t>(rv * R + ru)];
            double* Lr = Lrow;
            if (R > 1) {
                for (int i = 0; i < ncu; ++i) tmp[i] = Lrow[i * R + ru];
                Lr = tmp;
            }
            for (int e = 0; e < p.nseg; ++e) {
                // p.off = du + dv Wu with |du| <= 1: split it into the row and column shifts.
                const int dv = floor_div(p.off[e] + 1, s.Wu), du = p.off[e] - dv * s.Wu;
                advance_segment(ncu, Lr, cv + 1 + dv, 1 + cu0 + du, s.Wu, span, K, Us, phi, p.len[e], p.w[e]);
            }
            if (R > 1)
                for (int i = 0; i < ncu; ++i) Lrow[i * R + ru] = tmp[i];
        }

        if (s.per_u) {
            double* b = B + s.row(qv2);
            const int d = ((g.dSu % s.NuS) + s.NuS) % s.NuS;  // slot i goes to (i + d) mod NuS
            if (v_out) {
                for (int i = 0; i < nU; ++i) esc.v[qv2 < 0 ? 0 : 1] += Lrow[i];
            } else {
                std::copy(Lrow, Lrow + (s.NuS - d), b + d);
                std::copy(Lrow + (s.NuS - d), Lrow + s.NuS, b);
            }
            continue;
        }
        // Rays whose next slot u_lo + i + dSu lies outside [0, NuS) leave the domain.
        const int i_out_lo = std::clamp(-u_lo - g.dSu, 0, nU), i_out_hi = std::clamp(s.NuS - u_lo - g.dSu, i_out_lo, nU);
        for (int i = 0; i < i_out_lo; ++i) esc.u[0] += Lrow[i];
        for (int i = i_out_hi; i < nU; ++i) esc.u[1] += Lrow[i];
        if (v_out) {
            for (int qu2 = w_lo; qu2 < w_hi; ++qu2) esc.v[qv2 < 0 ? 0 : 1] += Lrow[qu2 - g.dSu - u_lo];
        } else {
            double* b = B + s.row(qv2);
            std::copy(Lrow + (w_lo - g.dSu - u_lo), Lrow + (w_hi - g.dSu - u_lo), b + w_lo);
        }
    }
}

// The rank's part of the map geometry for face f.
struct MapFrame {
    int f, a, s, ua, va;
    Int3 n;                // global cells
    int alo, ahi;          // local layers (global indices) along a
    int nu, vlo, vhi;      // u: all cells; v: local range (global indices)
    int Wu, Wv;            // padded plane: (nu + 2) x (vhi - vlo + 2)
    size_t plane() const { return static_cast<size_t>(Wu) * Wv; }
    int layers() const { return ahi - alo; }
    // Global cell of padded (layer la, pv, pu).
    Int3 cell(int la, int pv, int pu) const {
        Int3 c{};
        c[a] = alo + la;
        c[va] = vlo + pv - 1;
        c[ua] = pu - 1;
        return c;
    }
};

// Padded copy of comp c of field f on the map's planes: wrapped across periodic x/y, the
// field's z ghost where a neighbour owns the cell, 0 outside the domain.
void fill_padded(const MapFrame& m, const Decomposition& d, const Field<double>& f, int comp, double* out) {
    const bool per_u = d.periodic(m.ua);  // u is x or y, never z
    for (int la = 0; la < m.layers(); ++la)
        for (int pv = 0; pv < m.Wv; ++pv, out += m.Wu) {
            Int3 c = m.cell(la, pv, 1);  // the row's cell at u = 0
            int& v = c[m.va];
            if (v < 0 || v >= m.n[m.va]) {
                if (m.va == 2 || !d.periodic(m.va)) {
                    std::fill(out, out + m.Wu, 0.0);
                    continue;
                }
                v = (v + m.n[m.va]) % m.n[m.va];
            }
            const double* row = &f(c[0], c[1], c[2], comp);
            const std::ptrdiff_t st = f.stride(m.ua);
            for (int i = 0; i < m.nu; ++i) out[i + 1] = row[i * st];
            out[0] = per_u ? out[m.nu] : 0.0;
            out[m.nu + 1] = per_u ? out[1] : 0.0;
        }
}

}  // namespace

void sweep_map(const Decomposition& d, int face, const MapInputs& in, MapAccumulators& acc) {
    const Angular& ang = *in.angular;
    const int p = ang.p(), k2 = ang.k() * ang.k(), nm = ang.coarse_bins(), R = in.refinement;
    MapFrame m{};
    m.f = face;
    m.a = face_axis(face);
    m.s = face_sign(face);
    m.ua = u_axis(m.a);
    m.va = v_axis(m.a);
    m.n = d.global().shape();
    const Box& own = d.local();
    m.alo = own.lo[m.a];
    m.ahi = own.hi[m.a];
    m.nu = m.n[m.ua];
    m.vlo = own.lo[m.va];
    m.vhi = own.hi[m.va];
    m.Wu = m.nu + 2;
    m.Wv = m.vhi - m.vlo + 2;
    const size_t plane = m.plane();
    const bool z_map = m.a == 2;

    // Snapshot Ũ of this face's coarse bins (with the neighbours' z ghost planes); those bins
    // of U are then emptied, and U's ghosts become deposit scratch.
    Field<double>& U = *acc.U;
    exchange_halo(U, d);
    std::vector<double> K(plane * static_cast<size_t>(m.layers()));
    std::vector<double> Us(K.size() * static_cast<size_t>(k2));
    fill_padded(m, d, *in.kappa, 0, K.data());
    for (int b = 0; b < k2; ++b) fill_padded(m, d, U, face * k2 + b, Us.data() + static_cast<size_t>(b) * K.size());
    // Per padded row, the columns that hold every cell with kappa > 0 or Ũ > 0 in any of the
    // face's coarse bins; outside them rays cross vacuum (advance_rays_vacuum).
    std::vector<MediumSpan> span(static_cast<size_t>(m.layers()) * m.Wv);
    for (size_t r = 0; r < span.size(); ++r) {
        auto empty = [&](int col) {
            if (K[r * m.Wu + col] != 0.0) return false;
            for (int b = 0; b < k2; ++b)
                if (Us[static_cast<size_t>(b) * K.size() + r * m.Wu + col] != 0.0) return false;
            return true;
        };
        int lo = 0, hi = m.Wu;
        while (lo < hi && empty(lo)) ++lo;
        while (hi > lo && empty(hi - 1)) --hi;
        span[r] = {lo, hi};
    }
    {
        const Box& al = U.allocated();
        for_each_cell(al, [&](int i, int j, int k) {
            double* u = &U(i, j, k);
            if (!own.contains(i, j, k)) std::fill(u, u + nm, 0.0);
            else std::fill(u + face * k2, u + (face + 1) * k2, 0.0);
        });
    }

    SlotLayout sl{};
    sl.R = R;
    sl.NuS = m.nu * R;
    sl.NvS = (m.vhi - m.vlo) * R;
    sl.Wu = m.Wu;
    sl.per_u = m.ua != 2 && d.periodic(m.ua);
    sl.per_v = m.va != 2 && d.periodic(m.va);
    const int z_lo = d.neighbor(2, -1), z_hi = d.neighbor(2, 1);
    sl.nb_lo = !z_map && z_lo != MPI_PROC_NULL;
    sl.nb_hi = !z_map && z_hi != MPI_PROC_NULL;

    // Per map direction (local index 0..p²-1): tangents, path per step, weights.
    const int nd = p * p;
    std::vector<double> tu(static_cast<size_t>(nd)), tv(tu.size()), path(tu.size()), wn(tu.size()), ef(tu.size());
    std::vector<double> D(static_cast<size_t>(nd * nm));
    bool isotropic = true;
    for (int l = 0; l < nd; ++l) {
        const int n = face * nd + l;
        tu[static_cast<size_t>(l)] = ang.tangent(l % p);
        tv[static_cast<size_t>(l)] = ang.tangent(l / p);
        const double wa = std::abs(ang.direction(n)[m.a]);
        path[static_cast<size_t>(l)] = in.h / wa;
        wn[static_cast<size_t>(l)] = ang.solid_angle(n) / (R * R);
        ef[static_cast<size_t>(l)] = ang.solid_angle(n) * wa * in.h * in.h / (R * R);
        for (int c = 0; c < nm; ++c) {
            D[static_cast<size_t>(l * nm + c)] = (*in.deposit)[static_cast<size_t>(n * nm + c)];
            if (D[static_cast<size_t>(l * nm + c)] != D[static_cast<size_t>(c)]) isotropic = false;
        }
    }

    // Deposit coefficients per direction (gather_kernel.h): [nd][nc], columns 1, ω̄^n (flux),
    // P^{n,m}/|Ω^m| (anisotropic scattering).
    const int nc_fluence = in.flux ? 4 : 1, nc = nc_fluence + (isotropic ? 0 : nm);
    std::vector<double> C(static_cast<size_t>(nd * nc));
    for (int l = 0; l < nd; ++l) {
        double* c = C.data() + static_cast<size_t>(l * nc);
        *c++ = 1.0;
        if (in.flux)
            for (int ax = 0; ax < 3; ++ax) *c++ = ang.mean_direction(face * nd + l)[ax];
        if (!isotropic)
            for (int mm = 0; mm < nm; ++mm) *c++ = D[static_cast<size_t>(l * nm + mm)];
    }
    std::vector<double> phi(plane * static_cast<size_t>(nd), 0.0);
    std::vector<double> rows(static_cast<size_t>(nc) * static_cast<size_t>(m.nu));
    const double* tot = rows.data();
    const double* Fr = tot + (in.flux ? m.nu : 0);
    const double* Sr = tot + (in.flux ? 4 : 1) * m.nu;
    // Folds periodic pads, then deposits the step's path integrals of directions [l0, l1) in
    // local layer la: fluence, flux and the scattered light into every coarse bin (eq. 5).
    auto deposit = [&](int la, int l0, int l1) {
        for (int l = l0; l < l1; ++l) {
            double* ph = phi.data() + plane * static_cast<size_t>(l);
            if (sl.per_u)
                for (int pv = 0; pv < m.Wv; ++pv) {
                    double* r = ph + static_cast<size_t>(pv) * m.Wu;
                    r[m.nu] += r[0];
                    r[1] += r[m.nu + 1];
                    r[0] = r[m.nu + 1] = 0.0;
                }
            if (sl.per_v) {
                const int nv = m.vhi - m.vlo;
                for (int pu = 0; pu < m.Wu; ++pu) {
                    ph[static_cast<size_t>(nv) * m.Wu + pu] += ph[pu];
                    ph[static_cast<size_t>(m.Wu) + pu] += ph[static_cast<size_t>(nv + 1) * m.Wu + pu];
                    ph[pu] = ph[static_cast<size_t>(nv + 1) * m.Wu + pu] = 0.0;
                }
            }
        }
        const double* Kl = K.data() + plane * static_cast<size_t>(la);
        const size_t nu = static_cast<size_t>(m.nu);
        for (int pv = 0; pv < m.Wv; ++pv) {
            const bool ghost_row = pv == 0 || pv == m.Wv - 1;
            const bool keep = !ghost_row || (pv == 0 ? sl.nb_lo : sl.nb_hi);
            const size_t c0 = static_cast<size_t>(pv) * m.Wu + 1;
            if (!keep) {
                for (int l = l0; l < l1; ++l) std::fill_n(phi.data() + plane * static_cast<size_t>(l) + c0, nu, 0.0);
                continue;
            }
            // Row sums over the directions: fluence, flux, and Σ_n P^{n,m}/|Ω^m| φ_n per bin m,
            // the last only inside the row's medium span (nothing scatters in vacuum).
            const MediumSpan& sp = span[static_cast<size_t>(la) * m.Wv + pv];
            const int i_lo = std::clamp(sp.lo - 1, 0, m.nu), i_hi = std::clamp(sp.hi - 1, i_lo, m.nu);
            auto gather = [&](int i0, int i1, int ncols) {
                if (i1 > i0)
                    gather_directions(i1 - i0, l1 - l0, phi.data() + plane * static_cast<size_t>(l0) + c0 + i0, plane,
                                      C.data() + static_cast<size_t>(l0) * nc, nc, ncols, rows.data() + i0, nu);
            };
            gather(0, i_lo, nc_fluence);
            gather(i_lo, i_hi, nc);
            gather(i_hi, m.nu, nc_fluence);
            // Row start in the fields and their strides along u.
            const Int3 g = m.cell(la, pv, 1);
            double* fl = &(*acc.fluence)(g[0], g[1], g[2]);
            double* fx = in.flux ? &(*acc.flux)(g[0], g[1], g[2]) : nullptr;
            double* u = &U(g[0], g[1], g[2]);
            const std::ptrdiff_t s_fl = acc.fluence->stride(m.ua), s_u = U.stride(m.ua);
            const std::ptrdiff_t s_fx = in.flux ? acc.flux->stride(m.ua) : 0;
            for (size_t i = 0; i < nu; ++i, fl += s_fl, u += s_u, fx += s_fx) {
                if (tot[i] == 0.0) continue;
                *fl += tot[i];
                if (in.flux)
                    for (int ax = 0; ax < 3; ++ax) fx[ax] += Fr[static_cast<size_t>(ax) * nu + i];
                const double sigma_s = in.albedo * Kl[c0 + i];
                if (sigma_s == 0.0) continue;
                if (isotropic)
                    for (int mm = 0; mm < nm; ++mm) u[mm] += sigma_s * D[static_cast<size_t>(mm)] * tot[i];
                else
                    for (int mm = 0; mm < nm; ++mm) u[mm] += sigma_s * Sr[static_cast<size_t>(mm) * nu + i];
            }
        }
    };

    StepGeometry geo;
    std::vector<double> work;
    auto layer_of_step = [&](long t) { return m.s > 0 ? static_cast<int>(t) : m.n[m.a] - 1 - static_cast<int>(t); };
    auto step_of_layer = [&](int layer) { return static_cast<long>(m.s > 0 ? layer : m.n[m.a] - 1 - layer); };
    auto run_direction = [&](int l, long t, const double* A, double* B) {
        const int la = layer_of_step(t % m.n[m.a]) - m.alo;
        step_geometry(tu[static_cast<size_t>(l)], tv[static_cast<size_t>(l)], t, R, path[static_cast<size_t>(l)],
                      wn[static_cast<size_t>(l)], m.Wu, geo);
        const int mb = ang.coarse_of(face * nd + l) - face * k2;
        Escapes esc;
        transport_step(geo, tu[static_cast<size_t>(l)], tv[static_cast<size_t>(l)], sl,
                       span.data() + static_cast<size_t>(la) * m.Wv, K.data() + plane * static_cast<size_t>(la),
                       Us.data() + K.size() * static_cast<size_t>(mb) + plane * static_cast<size_t>(la),
                       phi.data() + plane * static_cast<size_t>(l), A, B, esc, work);
        const double e = ef[static_cast<size_t>(l)];
        for (int side = 0; side < 2; ++side) {
            acc.escaped[m.ua][side] += esc.u[side] * e;
            acc.escaped[m.va][side] += esc.v[side] * e;
        }
    };
    const size_t ds = sl.dir_size();
    // Power still carried by the map (this rank's slots), W.
    auto map_power = [&](int l, const double* A) {
        double sum = 0.0;
        for (int qv = 0; qv < sl.NvS; ++qv)
            for (int qu = 0; qu < sl.NuS; ++qu) sum += A[sl.row(qv) + static_cast<size_t>(qu)];
        return sum * ef[static_cast<size_t>(l)];
    };
    const int far_side = m.s > 0 ? 1 : 0;

    if (z_map) {
        // Pipelined down (or up) the slab chain, one group of p directions at a time
        // (solvers/sweep/chain.h): group grp's message is its p maps' rays leaving the slab.
        const size_t real = static_cast<size_t>(sl.NvS) * sl.NuS;
        std::vector<double> A(ds * static_cast<size_t>(p)), B(A.size());
        const long t_first = m.s > 0 ? step_of_layer(m.alo) : step_of_layer(m.ahi - 1);
        sweep::ChainGroups groups;
        groups.size.assign(static_cast<size_t>(p), real * static_cast<size_t>(p));
        const sweep::ChainStats chain = sweep::pass_down(d, m.s, groups, [&](int grp, sweep::ChainIO& io) {
            std::fill(A.begin(), A.end(), 0.0);
            std::fill(B.begin(), B.end(), 0.0);
            const std::span<const double> entering = io.in();
            if (!entering.empty())
                for (int l = 0; l < p; ++l)
                    std::copy(entering.begin() + static_cast<std::ptrdiff_t>(real * l),
                              entering.begin() + static_cast<std::ptrdiff_t>(real * (l + 1)),
                              A.begin() + static_cast<std::ptrdiff_t>(ds * l + sl.row(0)));
            for (long t = t_first; t < t_first + m.layers(); ++t) {
                for (int l = 0; l < p; ++l)
                    run_direction(grp * p + l, t, A.data() + ds * static_cast<size_t>(l), B.data() + ds * static_cast<size_t>(l));
                deposit(layer_of_step(t) - m.alo, grp * p, grp * p + p);
                std::swap(A, B);
            }
            const std::span<double> leaving = io.out();
            if (!leaving.empty()) {
                for (int l = 0; l < p; ++l)
                    std::copy(A.begin() + static_cast<std::ptrdiff_t>(ds * l + sl.row(0)),
                              A.begin() + static_cast<std::ptrdiff_t>(ds * l + sl.row(0) + real),
                              leaving.begin() + static_cast<std::ptrdiff_t>(real * l));
            } else {
                for (int l = 0; l < p; ++l)
                    acc.escaped[2][far_side] += map_power(grp * p + l, A.data() + ds * static_cast<size_t>(l));
            }
        });
        acc.wait_seconds += chain.wait_seconds;
    } else {
        // Every slab at once; rays crossing a slab boundary are exchanged after each step.
        std::vector<double> A(ds * static_cast<size_t>(nd), 0.0), B(A.size(), 0.0);
        std::vector<double> to_hi, to_lo, from_lo, from_hi;
        std::vector<int> dSv(static_cast<size_t>(nd));
        // A periodic map axis (x or y) is swept cyclically: the rays leaving the far face
        // re-enter at the near face (no new source after the first pass) until the power the
        // map still carries is below kCyclicTolerance of what it carried after the first pass.
        const bool cyclic = d.periodic(m.a);
        double first_pass_power = 0.0;
        for (long t = 0;; ++t) {
            if (t > 0 && t % m.n[m.a] == 0) {
                double power = 0.0;
                for (int l = 0; l < nd; ++l) power += map_power(l, A.data() + ds * static_cast<size_t>(l));
                if (!cyclic) {
                    acc.escaped[m.a][far_side] += power;
                    break;
                }
                MPI_Allreduce(MPI_IN_PLACE, &power, 1, MPI_DOUBLE, MPI_SUM, d.comm());
                if (t == m.n[m.a]) {
                    first_pass_power = power;
                    std::fill(Us.begin(), Us.end(), 0.0);
                }
                if (power <= kCyclicTolerance * first_pass_power || t >= kMaxCyclicPasses * m.n[m.a]) {
                    double mine = 0.0;
                    for (int l = 0; l < nd; ++l) mine += map_power(l, A.data() + ds * static_cast<size_t>(l));
                    acc.truncated += mine;
                    break;
                }
            }
            for (int l = 0; l < nd; ++l) {
                run_direction(l, t, A.data() + ds * static_cast<size_t>(l), B.data() + ds * static_cast<size_t>(l));
                dSv[static_cast<size_t>(l)] = geo.dSv;
            }
            to_hi.clear();
            to_lo.clear();
            size_t n_from_lo = 0, n_from_hi = 0;
            for (int l = 0; l < nd; ++l) {
                const int s = dSv[static_cast<size_t>(l)];
                const double* b = B.data() + ds * static_cast<size_t>(l);
                if (s > 0) {
                    to_hi.insert(to_hi.end(), b + sl.row(sl.NvS), b + sl.row(sl.NvS + s));
                    n_from_lo += static_cast<size_t>(s) * sl.NuS;
                } else if (s < 0) {
                    to_lo.insert(to_lo.end(), b + sl.row(s), b + sl.row(0));
                    n_from_hi += static_cast<size_t>(-s) * sl.NuS;
                }
            }
            from_lo.assign(n_from_lo, 0.0);
            from_hi.assign(n_from_hi, 0.0);
            const double t0 = MPI_Wtime();
            MPI_Sendrecv(to_hi.data(), sl.nb_hi ? static_cast<int>(to_hi.size()) : 0, MPI_DOUBLE, sl.nb_hi ? z_hi : MPI_PROC_NULL, 950,
                         from_lo.data(), static_cast<int>(from_lo.size()), MPI_DOUBLE, sl.nb_lo ? z_lo : MPI_PROC_NULL, 950,
                         d.comm(), MPI_STATUS_IGNORE);
            MPI_Sendrecv(to_lo.data(), sl.nb_lo ? static_cast<int>(to_lo.size()) : 0, MPI_DOUBLE, sl.nb_lo ? z_lo : MPI_PROC_NULL, 951,
                         from_hi.data(), static_cast<int>(from_hi.size()), MPI_DOUBLE, sl.nb_hi ? z_hi : MPI_PROC_NULL, 951,
                         d.comm(), MPI_STATUS_IGNORE);
            acc.wait_seconds += MPI_Wtime() - t0;
            size_t ilo = 0, ihi = 0;
            for (int l = 0; l < nd; ++l) {
                const int s = dSv[static_cast<size_t>(l)];
                double* b = B.data() + ds * static_cast<size_t>(l);
                if (s > 0 && sl.nb_lo) {
                    std::copy(from_lo.begin() + static_cast<std::ptrdiff_t>(ilo),
                              from_lo.begin() + static_cast<std::ptrdiff_t>(ilo + static_cast<size_t>(s) * sl.NuS), b + sl.row(0));
                    ilo += static_cast<size_t>(s) * sl.NuS;
                } else if (s < 0 && sl.nb_hi) {
                    std::copy(from_hi.begin() + static_cast<std::ptrdiff_t>(ihi),
                              from_hi.begin() + static_cast<std::ptrdiff_t>(ihi + static_cast<size_t>(-s) * sl.NuS),
                              b + sl.row(sl.NvS + s));
                    ihi += static_cast<size_t>(-s) * sl.NuS;
                }
            }
            deposit(layer_of_step(t % m.n[m.a]) - m.alo, 0, nd);
            std::swap(A, B);
        }
    }
    if (!z_map) {
        accumulate_halo(U, d, 2);
        accumulate_halo(*acc.fluence, d, 2);
        if (acc.flux) accumulate_halo(*acc.flux, d, 2);
    }
}

}  // namespace nimbus::lpm
