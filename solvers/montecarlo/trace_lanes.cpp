// GCC 12's AVX-512 intrinsics read an uninitialized _mm512_undefined_*() on purpose and warn
// about it where they are inlined (GCC PR 105593, fixed in GCC 13): silenced for this file only.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

#include "solvers/montecarlo/trace_lanes.h"

#include <immintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

namespace nimbus::mc {

bool lane_kernel_supported() {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
           __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
           __builtin_cpu_supports("avx512vl");
}

// Everything below is compiled for x86-64-v4 function by function (not the whole file: inline
// functions of shared headers instantiated here must stay baseline for the rest of the program).
#define NIMBUS_V4 __attribute__((target("arch=x86-64-v4")))
#define NIMBUS_V4_INLINE __attribute__((target("arch=x86-64-v4"), always_inline)) inline

namespace {

constexpr int kLanes = 8;
constexpr int kGroups = 2;
// Parked lanes served together: serving costs about the same for 1 or 8 lanes, while parked
// lanes idle. 4 of 8 measured best on the default cloud (3: -4%, 5: -1%, 6: -7%; alternating
// runs, solvers/montecarlo/README.md). Two groups in turn overlap their dependency chains.
constexpr int kParkedToServe = 4;

using vd = __m512d;
using vi = __m512i;
using m8 = __mmask8;

// Per-lane state in memory: the walk's (in registers during the passes, stored around serve())
// and what only serve() needs. Lane l of every array belongs to the path in lane l.
struct alignas(64) LaneStore {
    std::int64_t idx[kLanes];          // the cell (GridView::index)
    std::int64_t dstep[3][kLanes];     // index step per axis (± stride)
    double tn[3][kLanes];              // distance to the next face per axis
    double t[kLanes];                  // distance travelled in this flight (at a collision: to the point)
    double tau[kLanes];                // optical depth left
    double w[kLanes];                  // weight
    double inv[3][kLanes];             // 1 / |d_a| (+inf for a zero component)
    double d[3][kLanes];               // direction
    double frac[3][kLanes];            // position in the cell where the next flight starts
    std::uint64_t draws[kLanes];       // uniforms the path's stream has given (PathRng::draws)
    std::uint64_t block[4][kLanes];    // words of the stream's block draws / 4 (PathRng::next_draw_block)
    std::uint64_t photon[kLanes];      // photon index (the stream's counter words 1 and 2)
    // The flux of this serve's collisions (scatter_collided), added to the accumulators at the
    // end of serve(): its cells were prefetched, and the rest of serve hides the wait.
    alignas(32) double flux_add[kLanes][4];
    std::int64_t flux_cell[kLanes];
    m8 flux_lanes = 0;  // lanes with a flux_add to apply (none without the flux)
};

struct Walk {
    vi idx, sx, sy, sz;
    vd tx, ty, tz, t, tau, w, ix, iy, iz;
};

NIMBUS_V4_INLINE Walk load_walk(const LaneStore& s) {
    return {_mm512_load_si512(s.idx), _mm512_load_si512(s.dstep[0]), _mm512_load_si512(s.dstep[1]),
            _mm512_load_si512(s.dstep[2]), _mm512_load_pd(s.tn[0]), _mm512_load_pd(s.tn[1]),
            _mm512_load_pd(s.tn[2]), _mm512_load_pd(s.t), _mm512_load_pd(s.tau), _mm512_load_pd(s.w),
            _mm512_load_pd(s.inv[0]), _mm512_load_pd(s.inv[1]), _mm512_load_pd(s.inv[2])};
}

NIMBUS_V4_INLINE void store_walk(const Walk& w, LaneStore& s) {
    _mm512_store_si512(s.idx, w.idx);
    _mm512_store_si512(s.dstep[0], w.sx);
    _mm512_store_si512(s.dstep[1], w.sy);
    _mm512_store_si512(s.dstep[2], w.sz);
    _mm512_store_pd(s.tn[0], w.tx);
    _mm512_store_pd(s.tn[1], w.ty);
    _mm512_store_pd(s.tn[2], w.tz);
    _mm512_store_pd(s.t, w.t);
    _mm512_store_pd(s.tau, w.tau);
    _mm512_store_pd(s.w, w.w);
    _mm512_store_pd(s.inv[0], w.ix);
    _mm512_store_pd(s.inv[1], w.iy);
    _mm512_store_pd(s.inv[2], w.iz);
}

// ---- Philox-4x32-10 (philox.h) in lanes: counter words and outputs in the low 32 bits of
// 64-bit lanes, one stream per lane, the key common to all. ----
struct PhiloxKeys {
    vi k0[10], k1[10];  // the round keys, broadcast
};

NIMBUS_V4_INLINE void set_philox_keys(std::uint64_t seed, PhiloxKeys& k) {
    auto k0 = static_cast<std::uint32_t>(seed), k1 = static_cast<std::uint32_t>(seed >> 32);
    for (int r = 0; r < 10; ++r) {
        k.k0[r] = _mm512_set1_epi64(k0);
        k.k1[r] = _mm512_set1_epi64(k1);
        k0 += 0x9E3779B9u;
        k1 += 0xBB67AE85u;
    }
}

NIMBUS_V4_INLINE void philox(vi c0, vi c1, vi c2, vi c3, const PhiloxKeys& k, vi out[4]) {
    const vi M0 = _mm512_set1_epi64(0xD2511F53), M1 = _mm512_set1_epi64(0xCD9E8D57);
    const vi lo32 = _mm512_set1_epi64(0xFFFFFFFF);
    for (int r = 0; r < 10; ++r) {
        const vi p0 = _mm512_mul_epu32(M0, c0), p1 = _mm512_mul_epu32(M1, c2);
        // 0x96: a ^ b ^ c
        const vi n0 = _mm512_ternarylogic_epi64(_mm512_srli_epi64(p1, 32), c1, k.k0[r], 0x96);
        const vi n2 = _mm512_ternarylogic_epi64(_mm512_srli_epi64(p0, 32), c3, k.k1[r], 0x96);
        c1 = _mm512_and_si512(p1, lo32);
        c3 = _mm512_and_si512(p0, lo32);
        c0 = n0;
        c2 = n2;
    }
    out[0] = c0, out[1] = c1, out[2] = c2, out[3] = c3;
}

// Word `pos` (0..7) of the two consecutive blocks w[0..3], w[4..7], per lane.
NIMBUS_V4_INLINE vi select_word(vi pos, const vi w[8]) {
    const m8 b0 = _mm512_test_epi64_mask(pos, _mm512_set1_epi64(1));
    const m8 b1 = _mm512_test_epi64_mask(pos, _mm512_set1_epi64(2));
    const m8 b2 = _mm512_test_epi64_mask(pos, _mm512_set1_epi64(4));
    const vi l0 = _mm512_mask_blend_epi64(b0, w[0], w[1]), l1 = _mm512_mask_blend_epi64(b0, w[2], w[3]);
    const vi l2 = _mm512_mask_blend_epi64(b0, w[4], w[5]), l3 = _mm512_mask_blend_epi64(b0, w[6], w[7]);
    return _mm512_mask_blend_epi64(b2, _mm512_mask_blend_epi64(b1, l0, l1), _mm512_mask_blend_epi64(b1, l2, l3));
}

// PathRng::uniform's mapping of a 32-bit word: (word + 1/2) 2^-32, exactly.
NIMBUS_V4_INLINE vd uniform_of(vi word) {
    return _mm512_mul_pd(_mm512_add_pd(_mm512_cvtepu64_pd(word), _mm512_set1_pd(0.5)), _mm512_set1_pd(0x1p-32));
}

// Keeps, for the lanes of k, the block the next draw comes from: words[0..3] while pos < 4, else
// words[4..7] (pos counts draws from the start of words[0..3]).
NIMBUS_V4_INLINE void store_draw_block(LaneStore& st, m8 k, vi pos, const vi words[8]) {
    const m8 second = _mm512_cmpgt_epi64_mask(pos, _mm512_set1_epi64(3));
    for (int q = 0; q < 4; ++q)
        _mm512_mask_store_epi64(st.block[q], k, _mm512_mask_blend_epi64(second, words[q], words[4 + q]));
}

// The next uniform of every lane's stream (word `pos` of `words`); lanes in `take` move on.
NIMBUS_V4_INLINE vd next_uniform(vi& pos, m8 take, const vi words[8]) {
    const vd u = uniform_of(select_word(pos, words));
    pos = _mm512_mask_add_epi64(pos, take, pos, _mm512_set1_epi64(1));
    return u;
}

// ---- Math in lanes ----

// -ln(u) for u in (0, 1]: u = m 2^e with m in [3/4, 3/2), ln m = 2 atanh(s), s = (m-1)/(m+1),
// |s| <= 1/5, the series to s^23 (next term below 1e-17 of ln m); about 1 ulp.
NIMBUS_V4_INLINE vd minus_log(vd u) {
    const vd one = _mm512_set1_pd(1.0);
    const vd m = _mm512_getmant_pd(u, _MM_MANT_NORM_p75_1p5, _MM_MANT_SIGN_src);
    vd e = _mm512_getexp_pd(u);  // floor(log2 u)
    e = _mm512_mask_add_pd(e, _mm512_cmp_pd_mask(m, one, _CMP_LT_OQ), e, one);  // m < 1: u = m 2^(e+1)
    const vd s = _mm512_div_pd(_mm512_sub_pd(m, one), _mm512_add_pd(m, one));
    const vd z = _mm512_mul_pd(s, s);
    vd p = _mm512_set1_pd(1.0 / 23);
    for (const double c : {1.0 / 21, 1.0 / 19, 1.0 / 17, 1.0 / 15, 1.0 / 13, 1.0 / 11, 1.0 / 9, 1.0 / 7, 1.0 / 5, 1.0 / 3})
        p = _mm512_fmadd_pd(p, z, _mm512_set1_pd(c));
    // ln m = 2 s + 2 s z p
    const vd two_s = _mm512_add_pd(s, s);
    const vd ln_m = _mm512_fmadd_pd(_mm512_mul_pd(two_s, z), p, two_s);
    constexpr double ln2_hi = 0x1.62e42fefa3800p-1, ln2_lo = 0x1.ef35793c76730p-45;
    const vd ln_u = _mm512_fmadd_pd(e, _mm512_set1_pd(ln2_hi), _mm512_fmadd_pd(e, _mm512_set1_pd(ln2_lo), ln_m));
    return _mm512_sub_pd(_mm512_setzero_pd(), ln_u);
}

// sincos.h's cos(2π xi), sin(2π xi) in lanes (the same quadrant fold and Taylor series).
NIMBUS_V4_INLINE void sincos_2pi(vd xi, vd& c, vd& s) {
    const vd x = _mm512_mul_pd(_mm512_set1_pd(4.0), xi);
    const vi q = _mm512_cvttpd_epi64(x);
    vd r = _mm512_sub_pd(x, _mm512_cvtepi64_pd(q));
    const m8 fold = _mm512_cmp_pd_mask(r, _mm512_set1_pd(0.5), _CMP_GT_OQ);
    r = _mm512_mask_sub_pd(r, fold, _mm512_set1_pd(1.0), r);
    const vd th = _mm512_mul_pd(r, _mm512_set1_pd(std::numbers::pi / 2)), t2 = _mm512_mul_pd(th, th);
    vd ps = _mm512_set1_pd(-1.0 / 1307674368000);
    for (const double k : {1.0 / 6227020800, -1.0 / 39916800, 1.0 / 362880, -1.0 / 5040, 1.0 / 120, -1.0 / 6, 1.0})
        ps = _mm512_fmadd_pd(ps, t2, _mm512_set1_pd(k));
    const vd sn = _mm512_mul_pd(th, ps);
    vd pc = _mm512_set1_pd(1.0 / 20922789888000);
    for (const double k : {-1.0 / 87178291200, 1.0 / 479001600, -1.0 / 3628800, 1.0 / 40320, -1.0 / 720,
                           1.0 / 24, -1.0 / 2, 1.0})
        pc = _mm512_fmadd_pd(pc, t2, _mm512_set1_pd(k));
    const vd cs = pc;
    const vd a = _mm512_mask_blend_pd(fold, cs, sn), b = _mm512_mask_blend_pd(fold, sn, cs);  // cos α, sin α
    // angle = q π/2 + α: (c, s) = (a, b), (-b, a), (-a, -b), (b, -a) for q = 0..3
    const m8 q0 = _mm512_test_epi64_mask(q, _mm512_set1_epi64(1));
    const m8 q1 = _mm512_test_epi64_mask(q, _mm512_set1_epi64(2));
    const vd c0 = _mm512_mask_blend_pd(q0, a, b), s0 = _mm512_mask_blend_pd(q0, b, a);
    const vd neg = _mm512_set1_pd(-0.0);
    c = _mm512_mask_xor_pd(c0, q0 ^ q1, c0, neg);
    s = _mm512_mask_xor_pd(s0, q1, s0, neg);
}

// hg_sample_mu (src/physics/phase.h) in lanes.
NIMBUS_V4_INLINE vd hg_mu(double g, vd xi) {
    if (std::abs(g) < 1e-4) return _mm512_fnmadd_pd(_mm512_set1_pd(2.0), xi, _mm512_set1_pd(1.0));
    const vd den = _mm512_fmadd_pd(_mm512_set1_pd(2.0 * g), xi, _mm512_set1_pd(1.0 - g));
    const vd s = _mm512_div_pd(_mm512_set1_pd(1.0 - g * g), den);
    const vd mu = _mm512_div_pd(_mm512_fnmadd_pd(s, s, _mm512_set1_pd(1.0 + g * g)), _mm512_set1_pd(2.0 * g));
    return _mm512_min_pd(_mm512_max_pd(mu, _mm512_set1_pd(-1.0)), _mm512_set1_pd(1.0));
}

// turn_direction (photon.h) in lanes: (dx, dy, dz) turned to polar cosine mu, azimuth (c, s).
NIMBUS_V4_INLINE void turn(vd& dx, vd& dy, vd& dz, vd mu, vd c, vd s) {
    const vd one = _mm512_set1_pd(1.0);
    const vd sign = _mm512_or_pd(one, _mm512_and_pd(dz, _mm512_set1_pd(-0.0)));  // copysign(1, dz)
    const vd a = _mm512_div_pd(_mm512_set1_pd(-1.0), _mm512_add_pd(sign, dz));
    const vd b = _mm512_mul_pd(_mm512_mul_pd(dx, dy), a);
    const vd ux = _mm512_fmadd_pd(_mm512_mul_pd(sign, _mm512_mul_pd(dx, dx)), a, one);
    const vd uy = _mm512_mul_pd(sign, b), uz = _mm512_mul_pd(_mm512_sub_pd(_mm512_setzero_pd(), sign), dx);
    const vd vx = b, vy = _mm512_fmadd_pd(_mm512_mul_pd(dy, dy), a, sign);
    const vd vz = _mm512_sub_pd(_mm512_setzero_pd(), dy);
    const vd st = _mm512_sqrt_pd(_mm512_max_pd(_mm512_setzero_pd(), _mm512_fnmadd_pd(mu, mu, one)));
    const vd sc = _mm512_mul_pd(st, c), ss = _mm512_mul_pd(st, s);
    const vd nx = _mm512_fmadd_pd(ux, sc, _mm512_fmadd_pd(vx, ss, _mm512_mul_pd(dx, mu)));
    const vd ny = _mm512_fmadd_pd(uy, sc, _mm512_fmadd_pd(vy, ss, _mm512_mul_pd(dy, mu)));
    const vd nz = _mm512_fmadd_pd(uz, sc, _mm512_fmadd_pd(vz, ss, _mm512_mul_pd(dz, mu)));
    dx = nx, dy = ny, dz = nz;
}

// An empty-space jump's crossings of the cube's faces on an axis other than its exit axis
// (lanes in `k`): min(floor((t_exit - tn) |d_a|) + 1, e) faces, as grid_walk.h's jump().
NIMBUS_V4_INLINE void cross_faces(m8 k, vd t_exit, vd e, vd& tn, vd inv, vi dstep, const double* d, vi& idx) {
    k &= _mm512_cmp_pd_mask(tn, t_exit, _CMP_LE_OQ);
    const vd q = _mm512_mul_pd(_mm512_sub_pd(t_exit, tn), _mm512_abs_pd(_mm512_load_pd(d)));
    const vd fl = _mm512_roundscale_pd(q, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    const vd crossed = _mm512_min_pd(_mm512_add_pd(fl, _mm512_set1_pd(1.0)), e);
    tn = _mm512_mask3_fmadd_pd(crossed, inv, tn, k);
    idx = _mm512_mask_add_epi64(idx, k, idx, _mm512_mullo_epi64(_mm512_cvtpd_epi64(crossed), dstep));
}

// Where a light term's photons enter (photon.h, EntrySampler), as per-face tables the lanes
// index by their face number.
struct EntryTables {
    int nfaces = 0;
    double cumulative[3]{};
    vi axis, high, masked, nlive, mu;    // per face f in lane f (f < 3)
    const std::int32_t* live[3]{};       // live pixels of the masked faces
    std::array<int, 3> lo{}, hi{};
};

NIMBUS_V4_INLINE void set_entry_tables(const EntrySampler& e, EntryTables& t) {
    t.nfaces = e.nfaces;
    alignas(64) std::int64_t axis[kLanes]{}, high[kLanes]{}, masked[kLanes]{}, nlive[kLanes]{}, mu[kLanes]{};
    for (int f = 0; f < e.nfaces; ++f) {
        t.cumulative[f] = e.cumulative[f];
        axis[f] = e.face[f] / 2;
        high[f] = e.face[f] % 2;
        masked[f] = e.masked[f];
        nlive[f] = static_cast<std::int64_t>(e.live[f].size());
        const int a1 = (e.face[f] / 2 + 1) % 3;
        mu[f] = e.hi[static_cast<size_t>(a1)] - e.lo[static_cast<size_t>(a1)];
        t.live[f] = e.live[f].data();
    }
    t.axis = _mm512_load_si512(axis), t.high = _mm512_load_si512(high), t.masked = _mm512_load_si512(masked);
    t.nlive = _mm512_load_si512(nlive), t.mu = _mm512_load_si512(mu);
    t.lo = e.lo, t.hi = e.hi;
}

// What the kernel needs besides the lanes.
struct Context {
    const GridView& grid;
    const PhotonOptics& optics;
    const LightTerm& term;
    std::uint64_t seed;
    std::int64_t next, hi;  // the next photon to start, and the end of the range
    PhiloxKeys keys;        // set by run_lanes
    EntryTables entry;      // set by run_lanes for a light term
    std::vector<std::int64_t>& lit;
    PathTally& out;
    double* flux;  // the flux accumulators ([cell][4]: x, y, z, unused; trace_light.h), or null
    // Light photons started ahead, eight at a time (start_light_photons costs the same for one
    // lane as for eight): lanes [taken, ready) of `ahead` wait for an empty lane.
    LaneStore ahead{};
    int taken = 0, ready = 0;
};

// A new emitted photon in lane l (scalar: the same code and first free path as trace_photons).
void start_emitted_photon(Context& c, LaneStore& st, int l) {
    const std::int64_t p = c.next++;
    PathRng rng(c.seed, c.term.stream, static_cast<std::uint64_t>(p));
    PathState s;
    c.term.emitter->sample(rng, c.grid, s);
    st.tau[l] = -std::log(rng.uniform());
    st.draws[l] = rng.draws();
    for (int q = 0; q < 4; ++q) st.block[q][l] = rng.next_draw_block()[static_cast<size_t>(q)];
    st.photon[l] = static_cast<std::uint64_t>(p);
    st.idx[l] = s.idx;
    st.w[l] = 1.0;
    for (int a = 0; a < 3; ++a) {
        st.frac[a][l] = s.frac[static_cast<size_t>(a)];
        st.d[a][l] = s.d[a];
    }
}

// New light photons in the lanes of k, the next photon indices in lane order: EntrySampler::
// sample and the first free path -ln(u) (trace_photon), drawing the same uniforms.
NIMBUS_V4 void start_light_photons(Context& c, LaneStore& st, m8 k) {
    const EntryTables& T = c.entry;
    const GridView& g = c.grid;
    const vi lane = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
    // lane order: the i-th lane of k takes photon next + i
    const vi rank_in_k = _mm512_maskz_expand_epi64(k, lane);
    const vi photon = _mm512_add_epi64(_mm512_set1_epi64(c.next), rank_in_k);
    c.next += std::popcount(static_cast<unsigned>(k));
    const vi c1 = _mm512_and_si512(photon, _mm512_set1_epi64(0xFFFFFFFF)), c2 = _mm512_srli_epi64(photon, 32);
    const vi c3 = _mm512_set1_epi64(c.term.stream);
    vi words[8];
    philox(_mm512_setzero_si512(), c1, c2, c3, c.keys, words);
    philox(_mm512_set1_epi64(1), c1, c2, c3, c.keys, words + 4);
    vi pos = _mm512_setzero_si512();
    // The face: the first whose cumulative probability reaches xi.
    const vd xi = next_uniform(pos, k, words);
    vi face = _mm512_setzero_si512();
    for (int f = 0; f < T.nfaces - 1; ++f)
        face = _mm512_mask_add_epi64(face, _mm512_cmp_pd_mask(xi, _mm512_set1_pd(T.cumulative[f]), _CMP_GT_OQ),
                                     face, _mm512_set1_epi64(1));
    const vi axis = _mm512_permutexvar_epi64(face, T.axis);
    const m8 high = _mm512_test_epi64_mask(_mm512_permutexvar_epi64(face, T.high), _mm512_set1_epi64(1));
    const m8 masked = k & _mm512_test_epi64_mask(_mm512_permutexvar_epi64(face, T.masked), _mm512_set1_epi64(1));
    // A masked face's live pixel: (u, v) along the face's next two axes.
    vd pixel_u = _mm512_setzero_pd(), pixel_v = _mm512_setzero_pd();
    if (masked) {
        const vd u = next_uniform(pos, masked, words);
        const vd nlive = _mm512_cvtepi64_pd(_mm512_permutexvar_epi64(face, T.nlive));
        const vi pick = _mm512_min_epi64(_mm512_cvttpd_epi64(_mm512_mul_pd(u, nlive)),
                                         _mm512_sub_epi64(_mm512_cvtpd_epi64(nlive), _mm512_set1_epi64(1)));
        vi live = _mm512_setzero_si512();
        for (int f = 0; f < T.nfaces; ++f) {
            const m8 on = masked & _mm512_cmpeq_epi64_mask(face, _mm512_set1_epi64(f));
            if (on)
                live = _mm512_mask_mov_epi64(live, on, _mm512_cvtepi32_epi64(_mm512_mask_i64gather_epi32(
                                                          _mm256_setzero_si256(), on, pick, T.live[f], 4)));
        }
        // live = u + mu v, exactly divided in doubles (both far below 2^53)
        const vd p = _mm512_cvtepi64_pd(live), mu = _mm512_cvtepi64_pd(_mm512_permutexvar_epi64(face, T.mu));
        pixel_v = _mm512_roundscale_pd(_mm512_div_pd(p, mu), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
        pixel_u = _mm512_fnmadd_pd(pixel_v, mu, p);
    }
    const std::int64_t sy = g.n[0] + 2, sz = sy * (g.n[1] + 2);
    const std::int64_t stride[3] = {1, sy, sz};
    // index of the entry box's cell (0, 0, 0) in the walked grid (the box itself, or the domain)
    vi idx = _mm512_set1_epi64(g.index({T.lo[0] - g.origin[0], T.lo[1] - g.origin[1], T.lo[2] - g.origin[2]}));
    for (int a = 0; a < 3; ++a) {
        const m8 on_axis = k & _mm512_cmpeq_epi64_mask(axis, _mm512_set1_epi64(a));
        const m8 across = k & static_cast<m8>(~on_axis);
        const vd u = next_uniform(pos, across, words);
        // unmasked: uniform over the box's extent on this axis
        const double lo = T.lo[static_cast<size_t>(a)], ext = T.hi[static_cast<size_t>(a)] - T.lo[static_cast<size_t>(a)];
        const vd x = _mm512_fmadd_pd(u, _mm512_set1_pd(ext), _mm512_set1_pd(lo));
        const vd cell_x = _mm512_min_pd(_mm512_roundscale_pd(x, _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC),
                                        _mm512_set1_pd(T.hi[static_cast<size_t>(a)] - 1));
        vd frac = _mm512_sub_pd(x, cell_x);
        vd cell = _mm512_sub_pd(cell_x, _mm512_set1_pd(lo));
        // masked: the pixel's cell, u inside it
        const m8 first_after = masked & _mm512_cmpeq_epi64_mask(axis, _mm512_set1_epi64((a + 2) % 3));
        const m8 second_after = masked & _mm512_cmpeq_epi64_mask(axis, _mm512_set1_epi64((a + 1) % 3));
        cell = _mm512_mask_mov_pd(cell, first_after, pixel_u);
        cell = _mm512_mask_mov_pd(cell, second_after, pixel_v);
        frac = _mm512_mask_mov_pd(frac, masked & across, u);
        // the entry face itself: its first or last cell, at the face
        cell = _mm512_mask_mov_pd(cell, on_axis & high, _mm512_set1_pd(T.hi[static_cast<size_t>(a)] - 1 - lo));
        cell = _mm512_mask_mov_pd(cell, on_axis & static_cast<m8>(~high), _mm512_setzero_pd());
        frac = _mm512_mask_mov_pd(frac, on_axis, _mm512_mask_mov_pd(_mm512_setzero_pd(), high, _mm512_set1_pd(1.0)));
        idx = _mm512_add_epi64(idx, _mm512_mullo_epi64(_mm512_cvtpd_epi64(cell), _mm512_set1_epi64(stride[a])));
        _mm512_mask_store_pd(st.frac[a], k, frac);
        _mm512_mask_store_pd(st.d[a], k, _mm512_set1_pd(c.term.w[a]));
    }
    _mm512_mask_store_pd(st.tau, k, minus_log(next_uniform(pos, k, words)));
    store_draw_block(st, k, pos, words);
    _mm512_mask_store_epi64(st.draws, k, pos);
    _mm512_mask_store_epi64(st.photon, k, photon);
    _mm512_mask_store_epi64(st.idx, k, idx);
    _mm512_mask_store_pd(st.w, k, _mm512_set1_pd(1.0));
}

struct Masks {
    m8 active = 0;      // walking
    m8 tallying = 0;    // this flight's segments are diffuse (tallied)
    m8 collided = 0;    // parked at a collision (st.t: its distance, the walk's tn at it)
    m8 exited = 0;      // parked on the ghost layer along axis `last`
    m8 empty = 0xFF;    // no path
    m8 last[3] = {0, 0, 0};  // the axis of the lane's last step (a refilled lane keeps its old one:
                             // a path starts inside the box and steps before it can reach a ghost)
};

// Energy sums of a group's lanes (photon weights), reduced into PathTally at the end.
struct LaneSums {
    vd absorbed, roulette, escaped_direct, escaped[6];
};

// Where the walk stands at distance t of its flight, as the cell fractions (grid_walk.h's
// set_frac(t)), on the lanes in k and the axes their direction moves along (others keep theirs).
NIMBUS_V4_INLINE void store_fractions(LaneStore& st, m8 k) {
    const vd inf = _mm512_set1_pd(std::numeric_limits<double>::infinity());
    const vd t = _mm512_load_pd(st.t);
    for (int a = 0; a < 3; ++a) {
        const m8 moving = k & _mm512_cmp_pd_mask(_mm512_load_pd(st.inv[a]), inf, _CMP_NEQ_UQ);
        const vd left = _mm512_mul_pd(_mm512_sub_pd(_mm512_load_pd(st.tn[a]), t), _mm512_abs_pd(_mm512_load_pd(st.d[a])));
        const m8 up = _mm512_cmpgt_epi64_mask(_mm512_load_si512(st.dstep[a]), _mm512_setzero_si512());
        vd f = _mm512_mask_sub_pd(left, up, _mm512_set1_pd(1.0), left);
        f = _mm512_min_pd(_mm512_max_pd(f, _mm512_setzero_pd()), _mm512_set1_pd(1.0));
        _mm512_mask_store_pd(st.frac[a], moving, f);
    }
}

// The exited lanes: an unscattered path's weight escapes directly; a scattered one's through the
// domain face its straight path leaves by (grid_walk.h: the exit point, cell_of and
// domain_exit_face, ties to the exit axis, then to the lower axis).
NIMBUS_V4 void book_exits(const GridView& g, LaneStore& st, const Masks& m, LaneSums& sums) {
    const m8 E = m.exited;
    const vd w = _mm512_load_pd(st.w);
    sums.escaped_direct = _mm512_mask_add_pd(sums.escaped_direct, E & static_cast<m8>(~m.tallying), sums.escaped_direct, w);
    const m8 D = E & m.tallying;
    if (!D) return;
    store_fractions(st, D);
    // Back to the last cell inside, at its face on the exit axis.
    vi idx = _mm512_load_si512(st.idx);
    for (int a = 0; a < 3; ++a) {
        const m8 k = D & m.last[a];
        const vi dstep = _mm512_load_si512(st.dstep[a]);
        idx = _mm512_mask_sub_epi64(idx, k, idx, dstep);
        const m8 up = _mm512_cmpgt_epi64_mask(dstep, _mm512_setzero_si512());
        _mm512_mask_store_pd(st.frac[a], k, _mm512_mask_mov_pd(_mm512_setzero_pd(), up, _mm512_set1_pd(1.0)));
    }
    // cell_of in doubles: exact, the indices are far below 2^53.
    const double sy = g.n[0] + 2, sz = sy * (g.n[1] + 2);
    const vd fi = _mm512_cvtepi64_pd(idx);
    const vd kk = _mm512_roundscale_pd(_mm512_div_pd(fi, _mm512_set1_pd(sz)), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    const vd r = _mm512_fnmadd_pd(kk, _mm512_set1_pd(sz), fi);
    const vd jj = _mm512_roundscale_pd(_mm512_div_pd(r, _mm512_set1_pd(sy)), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    const vd ii = _mm512_fnmadd_pd(jj, _mm512_set1_pd(sy), r);
    const vd padded[3] = {ii, jj, kk};  // cell + 1
    const vd inf = _mm512_set1_pd(std::numeric_limits<double>::infinity());
    vd t_face[3], d[3];
    for (int b = 0; b < 3; ++b) {
        d[b] = _mm512_load_pd(st.d[b]);
        const vd x = _mm512_add_pd(_mm512_add_pd(padded[b], _mm512_set1_pd(g.origin[static_cast<size_t>(b)] - 1)),
                                   _mm512_load_pd(st.frac[b]));
        const m8 up = _mm512_cmp_pd_mask(d[b], _mm512_setzero_pd(), _CMP_GT_OQ);
        const vd along = _mm512_mask_sub_pd(x, up, _mm512_set1_pd(g.domain[static_cast<size_t>(b)]), x);
        const m8 valid = g.periodic[static_cast<size_t>(b)] ? 0 : _mm512_cmp_pd_mask(d[b], _mm512_setzero_pd(), _CMP_NEQ_OQ);
        t_face[b] = _mm512_mask_mul_pd(inf, valid, along, _mm512_load_pd(st.inv[b]));
    }
    vd t_best = t_face[2];
    vi best = _mm512_set1_epi64(2);
    for (int b = 0; b < 2; ++b) {
        t_best = _mm512_mask_mov_pd(t_best, m.last[b], t_face[b]);
        best = _mm512_mask_mov_epi64(best, m.last[b], _mm512_set1_epi64(b));
    }
    for (int b = 0; b < 3; ++b) {
        const m8 k = static_cast<m8>(~m.last[b]) & _mm512_cmp_pd_mask(t_face[b], t_best, _CMP_LT_OQ);
        t_best = _mm512_mask_mov_pd(t_best, k, t_face[b]);
        best = _mm512_mask_mov_epi64(best, k, _mm512_set1_epi64(b));
    }
    vd d_best = d[0];
    d_best = _mm512_mask_mov_pd(d_best, _mm512_cmpeq_epi64_mask(best, _mm512_set1_epi64(1)), d[1]);
    d_best = _mm512_mask_mov_pd(d_best, _mm512_cmpeq_epi64_mask(best, _mm512_set1_epi64(2)), d[2]);
    vi face = _mm512_add_epi64(best, best);
    face = _mm512_mask_add_epi64(face, _mm512_cmp_pd_mask(d_best, _mm512_setzero_pd(), _CMP_GT_OQ), face, _mm512_set1_epi64(1));
    for (int f = 0; f < 6; ++f) {
        const m8 k = D & _mm512_cmpeq_epi64_mask(face, _mm512_set1_epi64(f));
        sums.escaped[f] = _mm512_mask_add_pd(sums.escaped[f], k, sums.escaped[f], w);
    }
}

// The collided lanes: the flux's collision estimator on the lanes of `diffuse` (those whose
// flight was tallied), then implicit capture, roulette, HG scattering and the next free path
// (scatter_path in photon.h, in its order and with its draws). Returns the lanes whose path goes
// on; the others are ended.
NIMBUS_V4 m8 scatter_collided(Context& c, LaneStore& st, m8 C, m8 diffuse, LaneSums& sums) {
    if (c.flux && diffuse) {  // (w s / kappa) d in the collision's cell (photon.h)
        alignas(64) double kappa[kLanes], F[3][kLanes];
        for (m8 z = diffuse; z; z &= static_cast<m8>(z - 1)) {
            const int l = std::countr_zero(static_cast<unsigned>(z));
            kappa[l] = static_cast<double>(c.grid.voxel[st.idx[l]].kappa);
        }
        const vd ws = _mm512_mul_pd(_mm512_load_pd(st.w), _mm512_set1_pd(c.term.tally_scale));
        const vd wk = _mm512_maskz_div_pd(diffuse, ws, _mm512_load_pd(kappa));
        for (int a = 0; a < 3; ++a) _mm512_store_pd(F[a], _mm512_mul_pd(wk, _mm512_load_pd(st.d[a])));
        for (m8 z = diffuse; z; z &= static_cast<m8>(z - 1)) {
            const int l = std::countr_zero(static_cast<unsigned>(z));
            st.flux_cell[l] = st.idx[l];
            _mm_prefetch(reinterpret_cast<const char*>(c.flux + 4 * st.idx[l]), _MM_HINT_T0);
            _mm256_store_pd(st.flux_add[l], _mm256_set_pd(0.0, F[2][l], F[1][l], F[0][l]));
        }
        st.flux_lanes = diffuse;
    }
    store_fractions(st, C);  // the collision point, with the old direction
    c.out.collisions += std::popcount(static_cast<unsigned>(C));
    const double albedo = c.optics.albedo;
    vd w = _mm512_load_pd(st.w);
    sums.absorbed = _mm512_mask_add_pd(sums.absorbed, C, sums.absorbed, _mm512_mul_pd(w, _mm512_set1_pd(1.0 - albedo)));
    w = _mm512_mul_pd(w, _mm512_set1_pd(albedo));
    m8 alive = C & _mm512_cmp_pd_mask(w, _mm512_setzero_pd(), _CMP_GT_OQ);
    const m8 rr = alive & _mm512_cmp_pd_mask(w, _mm512_set1_pd(c.optics.roulette_weight), _CMP_LT_OQ);
    // The path's next uniforms: at most 4, from the block holding draw n (kept) and the next one.
    const vi n = _mm512_load_si512(st.draws), photon = _mm512_load_si512(st.photon);
    const vi block = _mm512_srli_epi64(n, 2);
    const vi c1 = _mm512_and_si512(photon, _mm512_set1_epi64(0xFFFFFFFF)), c2 = _mm512_srli_epi64(photon, 32);
    const vi c3 = _mm512_set1_epi64(c.term.stream);
    vi words[8];
    for (int q = 0; q < 4; ++q) words[q] = _mm512_load_si512(st.block[q]);
    philox(_mm512_add_epi64(block, _mm512_set1_epi64(1)), c1, c2, c3, c.keys, words + 4);
    vi pos = _mm512_and_si512(n, _mm512_set1_epi64(3));
    // Roulette below the weight threshold: survive with probability 1/2, weight x 2.
    const vd u_rr = next_uniform(pos, rr, words);
    const m8 survive = rr & _mm512_cmp_pd_mask(u_rr, _mm512_set1_pd(0.5), _CMP_LT_OQ);
    const m8 killed = rr & static_cast<m8>(~survive);
    sums.roulette = _mm512_mask_add_pd(sums.roulette, survive, sums.roulette, w);
    sums.roulette = _mm512_mask_sub_pd(sums.roulette, killed, sums.roulette, w);
    w = _mm512_mask_add_pd(w, survive, w, w);
    alive &= static_cast<m8>(~killed);
    // HG polar cosine, azimuth, the turn and the next free path.
    const vd mu = hg_mu(c.optics.g, next_uniform(pos, alive, words));
    vd cphi, sphi;
    sincos_2pi(next_uniform(pos, alive, words), cphi, sphi);
    const vd tau = minus_log(next_uniform(pos, alive, words));
    vd dx = _mm512_load_pd(st.d[0]), dy = _mm512_load_pd(st.d[1]), dz = _mm512_load_pd(st.d[2]);
    turn(dx, dy, dz, mu, cphi, sphi);
    _mm512_mask_store_pd(st.d[0], alive, dx);
    _mm512_mask_store_pd(st.d[1], alive, dy);
    _mm512_mask_store_pd(st.d[2], alive, dz);
    _mm512_mask_store_pd(st.tau, alive, tau);
    _mm512_mask_store_pd(st.w, alive, w);
    // draws: n + what each lane took (pos counts from n & 3)
    store_draw_block(st, alive, pos, words);
    _mm512_mask_store_epi64(st.draws, alive, _mm512_add_epi64(_mm512_andnot_si512(_mm512_set1_epi64(3), n), pos));
    return alive;
}

// The new flights' set-up on the lanes in k (the scalar walk's prologue): step, reciprocal of
// the direction, the first face distances from the fractions.
NIMBUS_V4_INLINE void set_up_flights(const GridView& g, LaneStore& st, m8 k) {
    const std::int64_t sy = g.n[0] + 2, sz = sy * (g.n[1] + 2);
    const std::int64_t stride[3] = {1, sy, sz};
    const vd inf = _mm512_set1_pd(std::numeric_limits<double>::infinity());
    for (int a = 0; a < 3; ++a) {
        const vd d = _mm512_load_pd(st.d[a]), f = _mm512_load_pd(st.frac[a]);
        const m8 up = _mm512_cmp_pd_mask(d, _mm512_setzero_pd(), _CMP_GE_OQ);
        const vd inv = _mm512_div_pd(_mm512_set1_pd(1.0), _mm512_abs_pd(d));
        const vi s = _mm512_mask_blend_epi64(up, _mm512_set1_epi64(-stride[a]), _mm512_set1_epi64(stride[a]));
        const vd left = _mm512_mask_sub_pd(f, up, _mm512_set1_pd(1.0), f);
        const m8 finite = _mm512_cmp_pd_mask(inv, inf, _CMP_NEQ_UQ);
        const vd first = _mm512_mask_mul_pd(inf, finite, left, inv);
        _mm512_mask_store_pd(st.inv[a], k, inv);
        _mm512_mask_store_epi64(st.dstep[a], k, s);
        _mm512_mask_store_pd(st.tn[a], k, first);
    }
    _mm512_mask_store_pd(st.t, k, _mm512_setzero_pd());
}

// Lane q of a started-ahead store into lane l of st: every field start_light_photons writes.
inline void move_start(const LaneStore& from, int q, LaneStore& st, int l) {
    st.idx[l] = from.idx[q];
    st.tau[l] = from.tau[q];
    st.w[l] = from.w[q];
    st.draws[l] = from.draws[q];
    st.photon[l] = from.photon[q];
    for (int a = 0; a < 3; ++a) {
        st.frac[a][l] = from.frac[a][q];
        st.d[a][l] = from.d[a][q];
    }
    for (int w = 0; w < 4; ++w) st.block[w][l] = from.block[w][q];
}

// Serves the parked lanes and refills the empty ones (trace_lanes.h, scheduling). On return
// every lane holding a path walks.
NIMBUS_V4 void serve(Context& c, LaneStore& st, Masks& m, LaneSums& sums) {
    book_exits(c.grid, st, m, sums);
    m.empty |= m.exited;
    m.exited = 0;
    m8 setup = 0;  // lanes whose next flight starts now
    if (const m8 C = m.collided) {
        const m8 alive = scatter_collided(c, st, C, C & m.tallying, sums);
        m.empty |= C & static_cast<m8>(~alive);
        m.tallying |= alive;
        setup |= alive;
        m.collided = 0;
    }
    // Empty lanes take the next photons, in index order.
    if (m.empty && (c.next < c.hi || c.taken < c.ready)) {
        m8 k = m.empty;
        for (std::int64_t left = c.hi - c.next + (c.ready - c.taken); std::popcount(static_cast<unsigned>(k)) > left;)
            k &= static_cast<m8>(~(0x80u >> std::countl_zero(static_cast<std::uint8_t>(k))));  // drop the highest lane
        for (m8 e = k; e; e &= static_cast<m8>(e - 1)) {
            const int l = std::countr_zero(static_cast<unsigned>(e));
            if (c.term.emitter) {
                start_emitted_photon(c, st, l);
                continue;
            }
            if (c.taken == c.ready) {
                c.ready = static_cast<int>(std::min<std::int64_t>(kLanes, c.hi - c.next));
                c.taken = 0;
                assert(c.ready > 0);  // k was trimmed to the photons left, so one is left here
                start_light_photons(c, c.ahead, static_cast<m8>((1u << c.ready) - 1));
            }
            move_start(c.ahead, c.taken++, st, l);
        }
        // emitted light is diffuse from its start, a light's photon only after its first scattering
        m.tallying = c.term.emitter ? (m.tallying | k) : (m.tallying & static_cast<m8>(~k));
        m.empty &= static_cast<m8>(~k);
        setup |= k;
    }
    if (setup) set_up_flights(c.grid, st, setup);
    m.active = static_cast<m8>(~m.empty);
    // The collisions' flux (scatter_collided): one 32-byte add per lane, one after the other
    // (lanes may share a cell). The cell of a lane refilled since is the collision's, kept in
    // flux_cell.
    for (m8 z = st.flux_lanes; z; z &= static_cast<m8>(z - 1)) {
        const int l = std::countr_zero(static_cast<unsigned>(z));
        double* f = c.flux + 4 * st.flux_cell[l];
        _mm256_storeu_pd(f, _mm256_add_pd(_mm256_loadu_pd(f), _mm256_load_pd(st.flux_add[l])));
    }
    st.flux_lanes = 0;
}

// One group of kLanes paths: their state, masks and energy sums.
struct Lanes {
    LaneStore st;
    Masks m;
    Walk W;
    LaneSums sums;
    std::int64_t segments;
};

// One pass of a group: every walking lane crosses one cell (or jumps), tallies its segment and
// parks at a collision or on leaving the box; parked lanes are served once kParkedToServe are.
NIMBUS_V4_INLINE void pass(Context& c, Lanes& L) {
    const GridView& g = c.grid;
    Voxel* const V = g.voxel;
    double* const tally_base = &V[0].tally;
    const vd ts = _mm512_set1_pd(c.term.tally_scale);
    const vd zero = _mm512_setzero_pd(), one = _mm512_set1_pd(1.0);
    const vi outside = _mm512_set1_epi64(outside_skip), one_i = _mm512_set1_epi64(1);
    const vi dummy = _mm512_set_epi64(-8, -7, -6, -5, -4, -3, -2, -1);
    LaneStore& st = L.st;
    Masks& m = L.m;
    Walk& W = L.W;
    alignas(64) std::int64_t I[kLanes];
    alignas(64) double A[kLanes];
    // Each lane's voxel: 16 bytes, kappa | skip in the low half, the tally in the high one.
    _mm512_store_si512(I, W.idx);
    __m128i head[4], tail[4];
    for (int p = 0; p < 4; ++p) {
        const __m128i a = _mm_load_si128(reinterpret_cast<const __m128i*>(V + I[2 * p]));
        const __m128i b = _mm_load_si128(reinterpret_cast<const __m128i*>(V + I[2 * p + 1]));
        head[p] = _mm_unpacklo_epi64(a, b);
        tail[p] = _mm_unpackhi_epi64(a, b);
    }
    const vi vox = _mm512_inserti64x4(_mm512_castsi256_si512(_mm256_set_m128i(head[1], head[0])),
                                      _mm256_set_m128i(head[3], head[2]), 1);
    const vd tl = _mm512_castsi512_pd(_mm512_inserti64x4(
        _mm512_castsi256_si512(_mm256_set_m128i(tail[1], tail[0])), _mm256_set_m128i(tail[3], tail[2]), 1));
    const vd kappa = _mm512_cvtps_pd(_mm256_castsi256_ps(_mm512_cvtepi64_epi32(vox)));
    const vi skip = _mm512_srli_epi64(vox, 32);
    const m8 ghost = m.active & _mm512_cmpeq_epi64_mask(skip, outside);
    const m8 stepping = m.active & static_cast<m8>(~ghost);
    // Empty-space jump across the cube of half-width e = skip - 1 (grid_walk.h); a unit
    // step is the jump with e = 0. Flights that tally empty cells (term.empty_cells) cross
    // them by unit steps.
    const m8 unit_only = c.term.empty_cells ? m.tallying : m8{0};
    const m8 jump = stepping & static_cast<m8>(~unit_only) & _mm512_cmpgt_epu64_mask(skip, one_i);
    const vd e = _mm512_sub_pd(_mm512_cvtepu64_pd(skip), one);
    const vd cx = _mm512_mask3_fmadd_pd(e, W.ix, W.tx, jump);
    const vd cy = _mm512_mask3_fmadd_pd(e, W.iy, W.ty, jump);
    const vd cz = _mm512_mask3_fmadd_pd(e, W.iz, W.tz, jump);
    // argmin of the face distances, ties to the higher axis
    const m8 y_le_x = _mm512_cmp_pd_mask(cy, cx, _CMP_LE_OQ);
    const vd m01 = _mm512_mask_blend_pd(y_le_x, cx, cy);
    const m8 z_le = _mm512_cmp_pd_mask(cz, m01, _CMP_LE_OQ);
    const vd t_exit = _mm512_mask_blend_pd(z_le, m01, cz);
    const m8 ax2 = z_le, ax1 = y_le_x & static_cast<m8>(~z_le), ax0 = static_cast<m8>(~(y_le_x | z_le));
    vi dsel = _mm512_mask_blend_epi64(ax1, W.sx, W.sy);
    dsel = _mm512_mask_blend_epi64(ax2, dsel, W.sz);
    {
        // The next pass's cells if every lane takes a unit step (most do): fetched now, while
        // this pass waits for its own.
        alignas(64) std::int64_t P[kLanes];
        _mm512_store_si512(P, _mm512_add_epi64(W.idx, dsel));
        for (int l = 0; l < kLanes; ++l) _mm_prefetch(reinterpret_cast<const char*>(V + P[l]), _MM_HINT_T0);
    }
    // The segment in this cell: tallied, or the collision inside it.
    const vd seg = _mm512_sub_pd(t_exit, W.t);
    const vd depth = _mm512_mul_pd(kappa, seg);
    const m8 medium = stepping & _mm512_cmp_pd_mask(kappa, zero, _CMP_GT_OQ);
    const m8 coll = medium & _mm512_cmp_pd_mask(depth, W.tau, _CMP_GE_OQ);
    const vd len = _mm512_mask_div_pd(seg, coll, W.tau, kappa);
    if (const m8 tallied = (c.term.empty_cells ? stepping : medium) & m.tallying) {
        const vd add = _mm512_mul_pd(_mm512_mul_pd(W.w, len), ts);
        const vi conflicts = _mm512_maskz_conflict_epi64(tallied, _mm512_mask_mov_epi64(dummy, tallied, W.idx));
        if (!_mm512_test_epi64_mask(conflicts, conflicts)) [[likely]] {
            _mm512_mask_i64scatter_pd(tally_base, tallied, _mm512_slli_epi64(W.idx, 1), _mm512_add_pd(tl, add), 8);
            for (m8 z = tallied & _mm512_cmp_pd_mask(tl, zero, _CMP_EQ_OQ); z; z &= static_cast<m8>(z - 1))
                c.lit.push_back(I[std::countr_zero(static_cast<unsigned>(z))]);
        } else {  // two lanes in one cell: one after the other
            _mm512_store_pd(A, add);
            for (m8 z = tallied; z; z &= static_cast<m8>(z - 1)) {
                const int l = std::countr_zero(static_cast<unsigned>(z));
                double& acc = V[I[l]].tally;
                if (acc == 0.0) c.lit.push_back(I[l]);
                acc += A[l];
            }
        }
        L.segments += std::popcount(static_cast<unsigned>(tallied));
    }
    // Advance the lanes that left their cell; a collided lane keeps its cell, t moves to the
    // collision point and the lane parks.
    const m8 adv = stepping & static_cast<m8>(~coll);
    W.tau = _mm512_mask_sub_pd(W.tau, adv, W.tau, depth);
    W.t = _mm512_mask_mov_pd(W.t, adv, t_exit);
    W.t = _mm512_mask_add_pd(W.t, coll, W.t, len);
    {
        const m8 jumped = jump & adv;
        cross_faces(jumped & static_cast<m8>(~ax0), t_exit, e, W.tx, W.ix, W.sx, st.d[0], W.idx);
        cross_faces(jumped & static_cast<m8>(~ax1), t_exit, e, W.ty, W.iy, W.sy, st.d[1], W.idx);
        cross_faces(jumped & static_cast<m8>(~ax2), t_exit, e, W.tz, W.iz, W.sz, st.d[2], W.idx);
    }
    W.tx = _mm512_mask_add_pd(W.tx, adv & ax0, t_exit, W.ix);
    W.ty = _mm512_mask_add_pd(W.ty, adv & ax1, t_exit, W.iy);
    W.tz = _mm512_mask_add_pd(W.tz, adv & ax2, t_exit, W.iz);
    dsel = _mm512_mask_mullo_epi64(dsel, jump, dsel, skip);  // (e + 1) cells along the exit axis
    W.idx = _mm512_mask_add_epi64(W.idx, adv, W.idx, dsel);
    m.last[0] = static_cast<m8>((m.last[0] & ~adv) | (ax0 & adv));
    m.last[1] = static_cast<m8>((m.last[1] & ~adv) | (ax1 & adv));
    m.last[2] = static_cast<m8>((m.last[2] & ~adv) | (ax2 & adv));
    // On the ghost layer: wrap a periodic axis, or the path has left the walked box.
    if (ghost) [[unlikely]] {
        const vi dstep[3] = {W.sx, W.sy, W.sz};
        for (int a = 0; a < 3; ++a) {
            const m8 k = ghost & m.last[a];
            if (!k) continue;
            if (g.periodic[a])
                W.idx = _mm512_mask_sub_epi64(W.idx, k, W.idx, _mm512_mullo_epi64(dstep[a], _mm512_set1_epi64(g.n[a])));
            else
                m.exited |= k;
        }
    }
    m.collided |= coll;
    m.active &= static_cast<m8>(~(coll | m.exited));
    if (std::popcount(static_cast<unsigned>(m.collided | m.exited)) >= kParkedToServe || !m.active) {
        store_walk(W, st);
        serve(c, st, m, L.sums);
        W = load_walk(st);
    }
}

NIMBUS_V4 void run_lanes(const GridView& g, const PhotonOptics& optics, const LightTerm& term, std::uint64_t seed,
                         std::int64_t lo, std::int64_t hi, std::vector<std::int64_t>& lit, PathTally& out,
                         double* flux) {
    Context c{g, optics, term, seed, lo, hi, {}, {}, lit, out, flux};
    set_philox_keys(seed, c.keys);
    if (!term.emitter) set_entry_tables(*term.entry, c.entry);
    // Two groups, passed in turn: their chains of dependent steps are independent, so the core
    // overlaps them.
    Lanes group[kGroups];
    for (Lanes& L : group) {
        L.st = LaneStore{};
        L.m = Masks{};
        L.sums.absorbed = L.sums.roulette = L.sums.escaped_direct = _mm512_setzero_pd();
        for (vd& e : L.sums.escaped) e = _mm512_setzero_pd();
        L.segments = 0;
        serve(c, L.st, L.m, L.sums);
        L.W = load_walk(L.st);
    }
    for (;;) {
        bool any = false;
        for (Lanes& L : group)
            if (L.m.active) {
                pass(c, L);
                any = true;
            }
        if (!any) break;
    }
    for (Lanes& L : group) {
        c.out.absorbed += _mm512_reduce_add_pd(L.sums.absorbed);
        c.out.roulette_net += _mm512_reduce_add_pd(L.sums.roulette);
        c.out.escaped_direct += _mm512_reduce_add_pd(L.sums.escaped_direct);
        for (int f = 0; f < 6; ++f) c.out.escaped_diffuse[f] += _mm512_reduce_add_pd(L.sums.escaped[f]);
        c.out.segments += L.segments;
    }
}

}  // namespace

void trace_photons_lanes(const GridView& grid, const PhotonOptics& optics, const LightTerm& term,
                         std::uint64_t seed, std::int64_t lo, std::int64_t hi,
                         std::vector<std::int64_t>& lit, PathTally& out, double* flux) {
    if (hi <= lo) return;
    run_lanes(grid, optics, term, seed, lo, hi, lit, out, flux);
}

}  // namespace nimbus::mc
