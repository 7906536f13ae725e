#include "solvers/lpm/map_sweep.h"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <span>

#include "solvers/lpm/gather_kernel.h"
#include "solvers/lpm/segment_kernel.h"
#include "solvers/sweep/chain.h"
#include "src/core/halo.h"
#include "src/core/mpi_counts.h"

namespace nimbus::lpm {
namespace {

// Cyclic sweeps along a periodic map axis (sweep_lateral): the filling passes end when the
// light the map still carries from its dark start is below this fraction of its power after
// the first cycle, or so that at most this many passes are run, the recorded ones included.
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
    size_t real_size() const { return static_cast<size_t>(NvS) * NuS; }  // real slots only
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

// The rank's part of the map of face f: axes, owned layers along the map axis, padded plane.
MapFrame map_frame(const Decomposition& d, int face) {
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
    return m;
}

// The rank's slots of map m, R rays per cell: periodic lateral axes wrap; a ±X/±Y map hands
// its rays to the z neighbours z_lo, z_hi (a ±Z map passes whole maps down the chain instead).
SlotLayout slot_layout(const MapFrame& m, const Decomposition& d, int R, int z_lo, int z_hi) {
    const bool z_map = m.a == 2;
    SlotLayout sl{};
    sl.R = R;
    sl.NuS = m.nu * R;
    sl.NvS = (m.vhi - m.vlo) * R;
    sl.Wu = m.Wu;
    sl.per_u = m.ua != 2 && d.periodic(m.ua);
    sl.per_v = m.va != 2 && d.periodic(m.va);
    sl.nb_lo = !z_map && z_lo != MPI_PROC_NULL;
    sl.nb_hi = !z_map && z_hi != MPI_PROC_NULL;
    return sl;
}

// One sweep of one map on this rank (the body of sweep_map): the map's frame and slots, the
// padded snapshots of kappa and Ũ with their medium spans, the per-direction tables, and the
// path integrals φ of the current step. Construction only reads the inputs (no messages);
// snapshot_and_clear and the sweeps are collective over d.comm().
class MapSweep {
public:
    MapSweep(const Decomposition& d, int face, const MapInputs& in, MapAccumulators& acc);

    // Snapshot Ũ of this face's coarse bins (with the neighbours' z ghost planes); those bins
    // of U are then emptied, and U's ghosts become deposit scratch.
    void snapshot_and_clear();
    bool z_map() const { return m_.a == 2; }
    // ±Z: the map pipelined down (or up) the slab chain, one group of p directions at a time.
    void sweep_z_chain();
    // ±X/±Y: every slab at once, rays exchanged across the slab boundaries after each step;
    // swept cyclically along a periodic map axis.
    void sweep_lateral();
    // After sweep_lateral: the deposits in the ghost layers are added to their owners.
    void accumulate_ghosts();

private:
    void direction_tables();
    void deposit_columns();
    bool vacuum(size_t at) const;
    void find_medium_spans();
    void clear_swept_bins();

    int layer_of_step(long t) const;
    long step_of_layer(int layer) const;
    // Direction l's block of the ray maps M (A_ or B_).
    double* rays(std::vector<double>& M, int l) const {
        return M.data() + ds_ * static_cast<size_t>(l);
    }
    int run_direction(int l, long t, const double* A, double* B);
    double map_power(int l, const double* A) const;

    void deposit(int la, int l0, int l1);
    void fold_periodic_pads(int l0, int l1);
    void gather_row(int la, int pv, int l0, int l1, size_t c0);
    void add_row(int la, int pv, size_t c0);

    void sweep_z_group(int grp, sweep::ChainIO& io);
    bool pass_ends_sweep(long t);
    void discard_path_integrals();
    void exchange_crossing_rays();
    void pack_crossing_rays();
    void unpack_crossing_rays();

    const Decomposition& d_;
    const MapInputs& in_;
    MapAccumulators& acc_;
    const Angular& ang_;
    Field<double>& U_;
    const int face_, p_, k2_, nm_, R_;
    const int nd_;  // map directions, p²
    const MapFrame m_;
    const size_t plane_;     // padded plane, Wu x Wv
    const int z_lo_, z_hi_;  // z neighbours (MPI_PROC_NULL at the domain's z faces)
    const SlotLayout sl_;
    const size_t ds_;     // slots of one direction, sl_.dir_size()
    const int far_side_;  // the face the map leaves through along its axis: 0 low, 1 high

    // Padded planes per local layer: kappa [layer][Wv][Wu], Ũ [face bin][layer][Wv][Wu].
    std::vector<double> K_, Us_;
    std::vector<MediumSpan> span_;  // [layer][pv]

    // Per map direction l (0..p²-1): tangents, path per step (m), fluence weight |Ω^n|/R²,
    // power per unit radiance |Ω^n| |ω_a| h²/R², and D [l][m] = P^{n,m}/|Ω^m|.
    std::vector<double> tu_, tv_, path_, wn_, ef_, D_;
    bool isotropic_ = true;     // D's rows all equal
    int nc_fluence_ = 1;        // deposit columns of the fluence (1) and flux (3)
    int nc_ = 1;                // all columns: those, then D's row when anisotropic
    std::vector<double> C_;     // deposit coefficients [l][nc]
    std::vector<double> phi_;   // path integrals of the step, [l][plane]
    std::vector<double> rows_;  // row sums over the directions, [nc][nu]

    StepGeometry geo_;
    std::vector<double> work_;
    std::vector<double> A_, B_;  // rays at the start and end of a step, ds_ per direction
    // ±X/±Y maps: each direction's slot shift along v in the step, the exchange buffers.
    std::vector<int> dSv_;
    std::vector<double> to_hi_, to_lo_, from_lo_, from_hi_;
    // Cyclic sweeps (periodic map axis): the lattice cycle K in passes, the map's rays (real
    // slots of every direction) after each of the last K filling passes (pass mod K; dark before
    // the first), the map's L1 power Σ |L| (all ranks) after pass K, the pass after which
    // recording ends and this rank's power when it started. Steps deposit and count escapes,
    // with weight record_weight_ = 1/K, only while recording_ (always, but in the filling passes
    // of a cyclic sweep).
    long cycle_ = 1, record_end_ = 0;
    std::vector<std::vector<double>> cycle_rays_;
    double cycle_l1_ = 0.0;
    double recorded_start_power_ = 0.0, record_weight_ = 1.0;
    bool recording_ = true;
};

MapSweep::MapSweep(const Decomposition& d, int face, const MapInputs& in, MapAccumulators& acc)
    : d_(d),
      in_(in),
      acc_(acc),
      ang_(*in.angular),
      U_(*acc.U),
      face_(face),
      p_(ang_.p()),
      k2_(ang_.k() * ang_.k()),
      nm_(ang_.coarse_bins()),
      R_(in.refinement),
      nd_(p_ * p_),
      m_(map_frame(d, face)),
      plane_(m_.plane()),
      z_lo_(d.neighbor(2, -1)),
      z_hi_(d.neighbor(2, 1)),
      sl_(slot_layout(m_, d, R_, z_lo_, z_hi_)),
      ds_(sl_.dir_size()),
      far_side_(m_.s > 0 ? 1 : 0) {
    direction_tables();
    deposit_columns();
    phi_.assign(plane_ * static_cast<size_t>(nd_), 0.0);
    rows_.assign(static_cast<size_t>(nc_) * static_cast<size_t>(m_.nu), 0.0);
}

// Per map direction (local index 0..p²-1): tangents, path per step, weights.
void MapSweep::direction_tables() {
    const size_t nd = static_cast<size_t>(nd_);
    for (std::vector<double>* v : {&tu_, &tv_, &path_, &wn_, &ef_}) v->assign(nd, 0.0);
    D_.assign(static_cast<size_t>(nd_ * nm_), 0.0);
    for (int l = 0; l < nd_; ++l) {
        const int n = face_ * nd_ + l;
        tu_[static_cast<size_t>(l)] = ang_.tangent(l % p_);
        tv_[static_cast<size_t>(l)] = ang_.tangent(l / p_);
        const double wa = std::abs(ang_.direction(n)[m_.a]);
        path_[static_cast<size_t>(l)] = in_.h / wa;
        wn_[static_cast<size_t>(l)] = ang_.solid_angle(n) / (R_ * R_);
        ef_[static_cast<size_t>(l)] = ang_.solid_angle(n) * wa * in_.h * in_.h / (R_ * R_);
        for (int c = 0; c < nm_; ++c) {
            D_[static_cast<size_t>(l * nm_ + c)] = (*in_.deposit)[static_cast<size_t>(n * nm_ + c)];
            if (D_[static_cast<size_t>(l * nm_ + c)] != D_[static_cast<size_t>(c)])
                isotropic_ = false;
        }
    }
}

// Deposit coefficients per direction (gather_kernel.h): [nd][nc], columns 1, ω̄^n (flux),
// P^{n,m}/|Ω^m| (anisotropic scattering).
void MapSweep::deposit_columns() {
    nc_fluence_ = in_.flux ? 4 : 1;
    nc_ = nc_fluence_ + (isotropic_ ? 0 : nm_);
    C_.assign(static_cast<size_t>(nd_ * nc_), 0.0);
    for (int l = 0; l < nd_; ++l) {
        double* c = C_.data() + static_cast<size_t>(l * nc_);
        *c++ = 1.0;
        if (in_.flux)
            for (int ax = 0; ax < 3; ++ax) *c++ = ang_.mean_direction(face_ * nd_ + l)[ax];
        if (!isotropic_)
            for (int mm = 0; mm < nm_; ++mm) *c++ = D_[static_cast<size_t>(l * nm_ + mm)];
    }
}

void MapSweep::snapshot_and_clear() {
    exchange_halo(U_, d_);
    K_.assign(plane_ * static_cast<size_t>(m_.layers()), 0.0);
    Us_.assign(K_.size() * static_cast<size_t>(k2_), 0.0);
    fill_padded(m_, d_, *in_.kappa, 0, K_.data());
    for (int b = 0; b < k2_; ++b)
        fill_padded(m_, d_, U_, face_ * k2_ + b, Us_.data() + static_cast<size_t>(b) * K_.size());
    find_medium_spans();
    clear_swept_bins();
}

// kappa = 0 and Ũ = 0 in every coarse bin of the face at padded index `at`.
bool MapSweep::vacuum(size_t at) const {
    if (K_[at] != 0.0) return false;
    for (int b = 0; b < k2_; ++b)
        if (Us_[static_cast<size_t>(b) * K_.size() + at] != 0.0) return false;
    return true;
}

// Per padded row, the columns that hold every cell with kappa > 0 or Ũ > 0 in any of the
// face's coarse bins; outside them rays cross vacuum (advance_rays_vacuum).
void MapSweep::find_medium_spans() {
    span_.assign(static_cast<size_t>(m_.layers()) * m_.Wv, MediumSpan{});
    for (size_t r = 0; r < span_.size(); ++r) {
        const size_t row = r * m_.Wu;
        int lo = 0, hi = m_.Wu;
        while (lo < hi && vacuum(row + lo)) ++lo;
        while (hi > lo && vacuum(row + hi - 1)) --hi;
        span_[r] = {lo, hi};
    }
}

// Empties the face's coarse bins of U in the owned cells and every bin in the ghost cells.
void MapSweep::clear_swept_bins() {
    const Box& own = d_.local();
    for_each_cell(U_.allocated(), [&](int i, int j, int k) {
        double* u = &U_(i, j, k);
        if (!own.contains(i, j, k)) {
            std::fill(u, u + nm_, 0.0);
        } else {
            std::fill(u + face_ * k2_, u + (face_ + 1) * k2_, 0.0);
        }
    });
}

// Global layer along the map axis that step t of a pass crosses, and the inverse.
int MapSweep::layer_of_step(long t) const {
    return m_.s > 0 ? static_cast<int>(t) : m_.n[m_.a] - 1 - static_cast<int>(t);
}
long MapSweep::step_of_layer(int layer) const {
    return static_cast<long>(m_.s > 0 ? layer : m_.n[m_.a] - 1 - layer);
}

// Step t of direction l: every ray of map A crosses one layer (eq. 4) into map B, its path
// integrals accumulated into φ_l; the light leaving the domain sideways is counted as escaped
// (while recording_). Returns the step's slot shift along v.
int MapSweep::run_direction(int l, long t, const double* A, double* B) {
    const int la = layer_of_step(t % m_.n[m_.a]) - m_.alo;
    const size_t i = static_cast<size_t>(l);
    step_geometry(tu_[i], tv_[i], t, R_, path_[i], wn_[i] * record_weight_, m_.Wu, geo_);
    const int mb = ang_.coarse_of(face_ * nd_ + l) - face_ * k2_;
    Escapes esc;
    transport_step(
        geo_, tu_[i], tv_[i], sl_, span_.data() + static_cast<size_t>(la) * m_.Wv,
        K_.data() + plane_ * static_cast<size_t>(la),
        Us_.data() + K_.size() * static_cast<size_t>(mb) + plane_ * static_cast<size_t>(la),
        phi_.data() + plane_ * i, A, B, esc, work_);
    if (!recording_) return geo_.dSv;  // a filling pass of a cyclic sweep
    const double e = ef_[i] * record_weight_;
    for (int side = 0; side < 2; ++side) {
        acc_.escaped[m_.ua][side] += esc.u[side] * e;
        acc_.escaped[m_.va][side] += esc.v[side] * e;
    }
    return geo_.dSv;
}

// Power still carried by direction l's map A (this rank's slots), W.
double MapSweep::map_power(int l, const double* A) const {
    double sum = 0.0;
    for (int qv = 0; qv < sl_.NvS; ++qv)
        for (int qu = 0; qu < sl_.NuS; ++qu) sum += A[sl_.row(qv) + static_cast<size_t>(qu)];
    return sum * ef_[static_cast<size_t>(l)];
}

// Folds periodic pads, then deposits the step's path integrals of directions [l0, l1) in
// local layer la: fluence, flux and the scattered light into every coarse bin (eq. 5).
void MapSweep::deposit(int la, int l0, int l1) {
    fold_periodic_pads(l0, l1);
    const size_t nu = static_cast<size_t>(m_.nu);
    for (int pv = 0; pv < m_.Wv; ++pv) {
        const bool ghost_row = pv == 0 || pv == m_.Wv - 1;
        const bool keep = !ghost_row || (pv == 0 ? sl_.nb_lo : sl_.nb_hi);
        const size_t c0 = static_cast<size_t>(pv) * m_.Wu + 1;
        if (!keep) {  // a pad row beyond the domain's v edge: nothing to deposit, φ cleared
            for (int l = l0; l < l1; ++l)
                std::fill_n(phi_.data() + plane_ * static_cast<size_t>(l) + c0, nu, 0.0);
            continue;
        }
        gather_row(la, pv, l0, l1, c0);
        add_row(la, pv, c0);
    }
}

// What a ray deposits in a periodic axis's pad cell belongs to the cell at the other end.
void MapSweep::fold_periodic_pads(int l0, int l1) {
    for (int l = l0; l < l1; ++l) {
        double* ph = phi_.data() + plane_ * static_cast<size_t>(l);
        if (sl_.per_u)
            for (int pv = 0; pv < m_.Wv; ++pv) {
                double* r = ph + static_cast<size_t>(pv) * m_.Wu;
                r[m_.nu] += r[0];
                r[1] += r[m_.nu + 1];
                r[0] = r[m_.nu + 1] = 0.0;
            }
        if (sl_.per_v) {
            const int nv = m_.vhi - m_.vlo;
            for (int pu = 0; pu < m_.Wu; ++pu) {
                ph[static_cast<size_t>(nv) * m_.Wu + pu] += ph[pu];
                ph[static_cast<size_t>(m_.Wu) + pu] += ph[static_cast<size_t>(nv + 1) * m_.Wu + pu];
                ph[pu] = ph[static_cast<size_t>(nv + 1) * m_.Wu + pu] = 0.0;
            }
        }
    }
}

// Row sums over the directions [l0, l1) of padded row pv (cells from column c0) into rows_:
// fluence, flux, and Σ_n P^{n,m}/|Ω^m| φ_n per bin m, the last only inside the row's medium
// span (nothing scatters in vacuum). Zeroes the row of φ.
void MapSweep::gather_row(int la, int pv, int l0, int l1, size_t c0) {
    const MediumSpan& sp = span_[static_cast<size_t>(la) * m_.Wv + pv];
    const int i_lo = std::clamp(sp.lo - 1, 0, m_.nu), i_hi = std::clamp(sp.hi - 1, i_lo, m_.nu);
    auto gather = [&](int i0, int i1, int ncols) {
        if (i1 > i0)
            gather_directions(i1 - i0, l1 - l0,
                              phi_.data() + plane_ * static_cast<size_t>(l0) + c0 + i0, plane_,
                              C_.data() + static_cast<size_t>(l0) * nc_, nc_, ncols,
                              rows_.data() + i0, static_cast<size_t>(m_.nu));
    };
    gather(0, i_lo, nc_fluence_);
    gather(i_lo, i_hi, nc_);
    gather(i_hi, m_.nu, nc_fluence_);
}

// Adds the row sums of padded row pv of local layer la into the fields: fluence, flux, and
// sigma_s times the scattered light into every coarse bin of U (eq. 5).
void MapSweep::add_row(int la, int pv, size_t c0) {
    const size_t nu = static_cast<size_t>(m_.nu);
    const double* tot = rows_.data();
    const double* Fr = tot + (in_.flux ? m_.nu : 0);
    const double* Sr = tot + (in_.flux ? 4 : 1) * m_.nu;
    const double* Kl = K_.data() + plane_ * static_cast<size_t>(la);
    // Row start in the fields and their strides along u.
    const Int3 g = m_.cell(la, pv, 1);
    double* fl = &(*acc_.fluence)(g[0], g[1], g[2]);
    double* fx = in_.flux ? &(*acc_.flux)(g[0], g[1], g[2]) : nullptr;
    double* u = &U_(g[0], g[1], g[2]);
    const std::ptrdiff_t s_fl = acc_.fluence->stride(m_.ua), s_u = U_.stride(m_.ua);
    const std::ptrdiff_t s_fx = in_.flux ? acc_.flux->stride(m_.ua) : 0;
    for (size_t i = 0; i < nu; ++i, fl += s_fl, u += s_u, fx += s_fx) {
        if (tot[i] == 0.0) continue;
        *fl += tot[i];
        if (in_.flux)
            for (int ax = 0; ax < 3; ++ax) fx[ax] += Fr[static_cast<size_t>(ax) * nu + i];
        const double sigma_s = in_.albedo * Kl[c0 + i];
        if (sigma_s == 0.0) continue;
        if (isotropic_)
            for (int mm = 0; mm < nm_; ++mm)
                u[mm] += sigma_s * D_[static_cast<size_t>(mm)] * tot[i];
        else
            for (int mm = 0; mm < nm_; ++mm)
                u[mm] += sigma_s * Sr[static_cast<size_t>(mm) * nu + i];
    }
}

// Pipelined down (or up) the slab chain, one group of p directions at a time
// (solvers/sweep/chain.h): group grp's message is its p maps' rays leaving the slab.
void MapSweep::sweep_z_chain() {
    A_.assign(ds_ * static_cast<size_t>(p_), 0.0);
    B_.assign(A_.size(), 0.0);
    sweep::ChainGroups groups;
    groups.size.assign(static_cast<size_t>(p_), sl_.real_size() * static_cast<size_t>(p_));
    const sweep::ChainStats chain = sweep::pass_down(
        d_, m_.s, groups, [&](int grp, sweep::ChainIO& io) { sweep_z_group(grp, io); });
    acc_.wait_seconds += chain.wait_seconds;
}

// Group grp (directions grp p .. grp p + p - 1) across the rank's slab: the rays entering from
// upstream (none at the chain's head), one step per layer, then the rays leaving handed
// downstream or, at the chain's end, counted as escaped through the far face.
void MapSweep::sweep_z_group(int grp, sweep::ChainIO& io) {
    const size_t real = sl_.real_size();
    std::fill(A_.begin(), A_.end(), 0.0);
    std::fill(B_.begin(), B_.end(), 0.0);
    const std::span<const double> entering = io.in();
    if (!entering.empty())
        for (int l = 0; l < p_; ++l)
            std::copy(entering.begin() + static_cast<std::ptrdiff_t>(real * l),
                      entering.begin() + static_cast<std::ptrdiff_t>(real * (l + 1)),
                      rays(A_, l) + sl_.row(0));
    const long t_first = m_.s > 0 ? step_of_layer(m_.alo) : step_of_layer(m_.ahi - 1);
    for (long t = t_first; t < t_first + m_.layers(); ++t) {
        for (int l = 0; l < p_; ++l) run_direction(grp * p_ + l, t, rays(A_, l), rays(B_, l));
        deposit(layer_of_step(t) - m_.alo, grp * p_, grp * p_ + p_);
        std::swap(A_, B_);
    }
    const std::span<double> leaving = io.out();
    if (!leaving.empty()) {
        for (int l = 0; l < p_; ++l)
            std::copy(rays(A_, l) + sl_.row(0), rays(A_, l) + sl_.row(0) + real,
                      leaving.begin() + static_cast<std::ptrdiff_t>(real * l));
    } else {
        for (int l = 0; l < p_; ++l)
            acc_.escaped[2][far_side_] += map_power(grp * p_ + l, rays(A_, l));
    }
}

// Every slab at once; rays crossing a slab boundary are exchanged after each step.
//
// A periodic map axis (x or y, n cells) is swept cyclically, the rays leaving the far face
// re-entering at the near one. A pass moves the lattice of a direction of tangents t by
// n t R slots along u and v (t = (2i + 1 - p)/p): it returns to its sub-slot offsets only
// after K = p / gcd(p, n R) passes (K = 1 when n R is a multiple of p). Summing passes of the
// first pass's light (source on the first pass only, the paper's cyclic mapping) is therefore
// exact only for K = 1: otherwise each pass's rays sit at other offsets, so the light from a
// given distance along a line is carried by rays up to a slot away, i.e. up to 1/|t| steps
// too near or too far (10-20% across the layers of a uniform periodic slab at n = 10, p = 6).
// Instead Ũ drives every pass: the filling passes only carry light (no deposits, no escapes
// counted) until what the map still lacks from its dark start is
// below kCyclicTolerance (the light of the first K passes still in it, L_k - L_{k-K}, in L1:
// the map's state is K-periodic once its dark start has died away), then the K passes of one
// lattice cycle are recorded with weight 1/K: every ray carries its whole straight line's
// light, the K offsets are averaged, and source = deposited + escaped + truncated holds
// exactly (truncated = what the map gained over the cycle, / K).
void MapSweep::sweep_lateral() {
    A_.assign(ds_ * static_cast<size_t>(nd_), 0.0);
    B_.assign(A_.size(), 0.0);
    dSv_.assign(static_cast<size_t>(nd_), 0);
    const int n = m_.n[m_.a];
    const bool cyclic = d_.periodic(m_.a);
    cycle_ = cyclic ? p_ / std::gcd(p_, n * R_) : 1;
    recording_ = !cyclic;
    record_weight_ = 1.0;
    cycle_rays_.assign(cyclic ? static_cast<size_t>(cycle_) : 0,
                       std::vector<double>(cyclic ? sl_.real_size() * static_cast<size_t>(nd_) : 0, 0.0));
    cycle_l1_ = 0.0;
    for (long t = 0;; ++t) {
        if (t > 0 && t % n == 0 && pass_ends_sweep(t)) break;
        for (int l = 0; l < nd_; ++l)
            dSv_[static_cast<size_t>(l)] = run_direction(l, t, rays(A_, l), rays(B_, l));
        exchange_crossing_rays();
        if (recording_) deposit(layer_of_step(t % n) - m_.alo, 0, nd_);
        else discard_path_integrals();
        std::swap(A_, B_);
    }
    record_weight_ = 1.0;
}

// At the end of a pass (step t): on an open map axis the sweep ends, the light left in the
// map leaving through the far face. On a periodic one (sweep_lateral), after filling pass k
// the recording of passes k+1 .. k+K starts when |L_k - L_{k-K}| <= kCyclicTolerance |L_K|
// (L_k: the map's rays after pass k; |.|: Σ over all rays and ranks of the power of |L|),
// when |L_k| = 0 (no light crosses the seam, so none from earlier periods ever arrives: the
// dark start is the steady state) or when the last of them would be the kMaxCyclicPasses-th;
// after the last one the sweep ends. The norm, not the signed power P_k: Ũ, and so L, has
// either sign after a DSA correction (solve_band.h), and then P_k - P_{k-K} (= |L_k - L_{k-K}|
// for light of one sign) can be negative or cancel long before the map is full; recording
// from there left the light still missing as `truncated` and shifted the fixed point.
bool MapSweep::pass_ends_sweep(long t) {
    double power = 0.0;
    for (int l = 0; l < nd_; ++l) power += map_power(l, rays(A_, l));
    if (!d_.periodic(m_.a)) {
        acc_.escaped[m_.a][far_side_] += power;
        return true;
    }
    const long pass = t / m_.n[m_.a];
    if (recording_) {
        if (pass < record_end_) return false;
        acc_.truncated += (power - recorded_start_power_) * record_weight_;
        return true;
    }
    // L1 power of the change over the last cycle and of the map, this rank's, then all ranks';
    // the map replaces pass k - K's in the ring.
    double l1[2] = {0.0, 0.0};
    const size_t real = sl_.real_size();
    double* last = cycle_rays_[static_cast<size_t>(pass % cycle_)].data();
    for (int l = 0; l < nd_; ++l, last += real) {
        const double* a = rays(A_, l) + sl_.row(0);
        double change = 0.0, size = 0.0;
        for (size_t i = 0; i < real; ++i) {
            change += std::abs(a[i] - last[i]);
            size += std::abs(a[i]);
            last[i] = a[i];
        }
        l1[0] += change * ef_[static_cast<size_t>(l)];
        l1[1] += size * ef_[static_cast<size_t>(l)];
    }
    MPI_Allreduce(MPI_IN_PLACE, l1, 2, MPI_DOUBLE, MPI_SUM, d_.comm());
    if (pass == cycle_) cycle_l1_ = l1[1];
    const bool filled = l1[1] == 0.0 || (pass >= cycle_ && l1[0] <= kCyclicTolerance * cycle_l1_);
    if (filled || pass + cycle_ >= kMaxCyclicPasses) {
        recording_ = true;
        record_end_ = pass + cycle_;
        record_weight_ = 1.0 / static_cast<double>(cycle_);
        recorded_start_power_ = power;
    }
    return false;
}

// A filling pass's step: its path integrals are not deposited.
void MapSweep::discard_path_integrals() { std::fill(phi_.begin(), phi_.end(), 0.0); }

// Hands the rays that left the rank's z range in this step (B's overflow rows) to the z
// neighbours and takes theirs into B's edge rows: one message per neighbour and step, all
// directions batched (tag 950 toward high z, 951 toward low z).
void MapSweep::exchange_crossing_rays() {
    pack_crossing_rays();
    const double t0 = MPI_Wtime();
    sendrecv_doubles(std::span<const double>(to_hi_.data(), sl_.nb_hi ? to_hi_.size() : 0),
                     sl_.nb_hi ? z_hi_ : MPI_PROC_NULL, from_lo_, sl_.nb_lo ? z_lo_ : MPI_PROC_NULL, 950, d_.comm());
    sendrecv_doubles(std::span<const double>(to_lo_.data(), sl_.nb_lo ? to_lo_.size() : 0),
                     sl_.nb_lo ? z_lo_ : MPI_PROC_NULL, from_hi_, sl_.nb_hi ? z_hi_ : MPI_PROC_NULL, 951, d_.comm());
    acc_.wait_seconds += MPI_Wtime() - t0;
    unpack_crossing_rays();
}

// Direction by direction, the dSv overflow rows of B beyond the high (dSv > 0) or low edge
// into to_hi_ / to_lo_; from_lo_ / from_hi_ sized for the neighbours' matching rows.
void MapSweep::pack_crossing_rays() {
    to_hi_.clear();
    to_lo_.clear();
    size_t n_from_lo = 0, n_from_hi = 0;
    for (int l = 0; l < nd_; ++l) {
        const int s = dSv_[static_cast<size_t>(l)];
        const double* b = rays(B_, l);
        if (s > 0) {
            to_hi_.insert(to_hi_.end(), b + sl_.row(sl_.NvS), b + sl_.row(sl_.NvS + s));
            n_from_lo += static_cast<size_t>(s) * sl_.NuS;
        } else if (s < 0) {
            to_lo_.insert(to_lo_.end(), b + sl_.row(s), b + sl_.row(0));
            n_from_hi += static_cast<size_t>(-s) * sl_.NuS;
        }
    }
    from_lo_.assign(n_from_lo, 0.0);
    from_hi_.assign(n_from_hi, 0.0);
}

// The rays received from the low (high) neighbour into the first (last) dSv rows of B's real
// slots, direction by direction.
void MapSweep::unpack_crossing_rays() {
    size_t ilo = 0, ihi = 0;
    for (int l = 0; l < nd_; ++l) {
        const int s = dSv_[static_cast<size_t>(l)];
        double* b = rays(B_, l);
        if (s > 0 && sl_.nb_lo) {
            std::copy(from_lo_.begin() + static_cast<std::ptrdiff_t>(ilo),
                      from_lo_.begin() +
                          static_cast<std::ptrdiff_t>(ilo + static_cast<size_t>(s) * sl_.NuS),
                      b + sl_.row(0));
            ilo += static_cast<size_t>(s) * sl_.NuS;
        } else if (s < 0 && sl_.nb_hi) {
            std::copy(from_hi_.begin() + static_cast<std::ptrdiff_t>(ihi),
                      from_hi_.begin() +
                          static_cast<std::ptrdiff_t>(ihi + static_cast<size_t>(-s) * sl_.NuS),
                      b + sl_.row(sl_.NvS + s));
            ihi += static_cast<size_t>(-s) * sl_.NuS;
        }
    }
}

void MapSweep::accumulate_ghosts() {
    accumulate_halo(U_, d_, 2);
    accumulate_halo(*acc_.fluence, d_, 2);
    if (acc_.flux) accumulate_halo(*acc_.flux, d_, 2);
}

}  // namespace

void sweep_map(const Decomposition& d, int face, const MapInputs& in, MapAccumulators& acc) {
    MapSweep map(d, face, in, acc);
    map.snapshot_and_clear();
    if (map.z_map()) {
        map.sweep_z_chain();
    } else {
        map.sweep_lateral();
        map.accumulate_ghosts();
    }
}

}  // namespace nimbus::lpm
