// The moment operators of the DOM sweep on blocks of cells (Kripke's LPlusTimes and LTimes),
// written as small dense matrix products with one octant's direction set (nd directions):
//   source  (moments -> directions):  S[c][n] = Σ_l A[c][l] P[l][n] + Σ_k s[c][k] Y[k][n]
//   moments (directions -> moments):  phi[c][k] += Σ_n wY[k][n] psi[c][n]
//                                     fluence[c] += Σ_n w_n psi[c][n]             (W/m²)
//                                     flux[c][a] += Σ_n w_n Ω_a,n psi[c][n]
// Y_k = real orthonormal harmonics, wY = w_n Y_k(Ω_n) (angular_set.h, angular_moments.h),
// A_l, P_l,n the first-collision amplitudes and phase values (cell_kernel.h); fluence and flux
// as in DESIGN §1. The fluence/flux reduction rides inside the moment product as one more 4-wide
// row (w, w Ω_x, w Ω_y, w Ω_z) per direction, so it costs one FMA per direction and cell.
//
// Two code paths with the same results up to round-off:
//  - avx2: AVX2 + FMA register-blocked micro-kernels (4 doubles per FMA, a block of cells per
//    pass so each loaded operator row feeds several cells), chosen at run time on CPUs that
//    have AVX2 and FMA (the build itself stays generic x86-64);
//  - portable: the per-cell kernels of cell_kernel.h (any CPU; any nd, nmom).
// NIMBUS_DOM_PORTABLE=1 in the environment forces the portable path (benchmarks, cross-checks).
//
// The operator objects are built once per octant and sweep (cheap: (nl + nmom) x nd values);
// the apply functions are pure (no MPI, no allocation) and may run on any subset of cells.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <vector>

#include "solvers/dom/cell_kernel.h"
#include "src/core/vec3.h"

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#define NIMBUS_DOM_HAVE_AVX2 1
#define NIMBUS_DOM_AVX2 __attribute__((target("avx2,fma")))
#else
#define NIMBUS_DOM_HAVE_AVX2 0
#endif

namespace nimbus::dom {

enum class MomentPath { automatic, portable, avx2 };

// True when this CPU has AVX2 and FMA.
inline bool avx2_available() {
#if NIMBUS_DOM_HAVE_AVX2
    static const bool ok = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    return ok;
#else
    return false;
#endif
}
// The automatic choice: the AVX2+FMA kernels where available, unless NIMBUS_DOM_PORTABLE is set.
inline bool avx2_selected() {
    static const bool forced_portable = [] {
        const char* e = std::getenv("NIMBUS_DOM_PORTABLE");
        return e != nullptr && *e != '\0' && *e != '0';
    }();
    return avx2_available() && !forced_portable;
}

// Moments -> directions of one octant. P: nl x nd, Y: nmom x nd (copied).
struct OctantSourceOp {
    int nd = 0, nl = 0, nmom = 0;
    int nv = 0;                // 4-wide vectors per cell: ceil(nd / 4)
    std::vector<double> P, Y;  // portable path
    std::vector<double> rows;  // avx2 path: (nl + nmom) rows of 4 nv, P rows then Y rows, zero padded
};

inline OctantSourceOp make_octant_source_op(int nd, int nl, int nmom, const double* P, const double* Y) {
    OctantSourceOp op;
    op.nd = nd;
    op.nl = nl;
    op.nmom = nmom;
    op.nv = (nd + 3) / 4;
    op.P.assign(P, P + static_cast<std::ptrdiff_t>(nl) * nd);
    op.Y.assign(Y, Y + static_cast<std::ptrdiff_t>(nmom) * nd);
    const int w = 4 * op.nv;
    op.rows.assign(static_cast<size_t>((nl + nmom) * w), 0.0);
    for (int r = 0; r < nl + nmom; ++r)
        for (int n = 0; n < nd; ++n)
            op.rows[static_cast<size_t>(r * w + n)] = r < nl ? P[r * nd + n] : Y[(r - nl) * nd + n];
    return op;
}

// Directions -> moments (+ fluence, flux) of one octant. wY: nmom x nd; weight, dir: nd each.
// nmom = 0 (wY unused): the fluence and flux alone, where no moments are needed.
struct OctantMomentOp {
    int nd = 0, nmom = 0;
    int mv = 0;                  // full 4-wide moment vectors: nmom / 4
    int tv = 0;                  // vectors per direction row: mv, + 1 for the nmom % 4 tail, + 1 (w, wΩ)
    std::vector<double> wY;      // portable path, nmom x nd
    std::vector<double> wdir;    // nd x 4: w, w Ω_x, w Ω_y, w Ω_z
    std::vector<double> rows;    // avx2 path: nd rows of 4 tv: wY[.][n] (zero padded to 4), then wdir[n]
};

inline OctantMomentOp make_octant_moment_op(int nd, int nmom, const double* wY, const double* weight,
                                            const Vec3* dir) {
    OctantMomentOp op;
    op.nd = nd;
    op.nmom = nmom;
    op.mv = nmom / 4;
    op.tv = op.mv + (nmom % 4 != 0 ? 1 : 0) + 1;
    op.wY.assign(wY, wY + static_cast<std::ptrdiff_t>(nmom) * nd);
    op.wdir.resize(static_cast<size_t>(4 * nd));
    for (int n = 0; n < nd; ++n) {
        const double w = weight[n];
        op.wdir[static_cast<size_t>(4 * n)] = w;
        for (int a = 0; a < 3; ++a) op.wdir[static_cast<size_t>(4 * n + 1 + a)] = w * dir[n][a];
    }
    const int w = 4 * op.tv;
    op.rows.assign(static_cast<size_t>(nd * w), 0.0);
    for (int n = 0; n < nd; ++n) {
        for (int k = 0; k < nmom; ++k) op.rows[static_cast<size_t>(n * w + k)] = wY[k * nd + n];
        for (int c = 0; c < 4; ++c)
            op.rows[static_cast<size_t>(n * w + 4 * (op.tv - 1) + c)] = op.wdir[static_cast<size_t>(4 * n + c)];
    }
    return op;
}

namespace detail {

inline void source_portable(const OctantSourceOp& op, std::ptrdiff_t ncell, const double* A, const double* s,
                            double* S) {
    const int nd = op.nd, nl = op.nl, nmom = op.nmom;
    for_octant_size(nd, [&](auto size) {
        constexpr int ND = decltype(size)::value;
        for (std::ptrdiff_t c = 0; c < ncell; ++c) {
            const double* a = nl > 0 ? A + c * nl : nullptr;
            if constexpr (ND > 0)
                cell_source_n<ND>(nl, nmom, a, op.P.data(), op.Y.data(), s + c * nmom, S + c * ND);
            else
                cell_source(nd, nl, nmom, a, op.P.data(), op.Y.data(), s + c * nmom, S + c * nd);
        }
    });
}

inline void moments_portable(const OctantMomentOp& op, int ncell, const double* psi, std::ptrdiff_t psi_stride,
                             double* phi, double* fluence, double* flux) {
    const int nd = op.nd, nmom = op.nmom;
    const double* wd = op.wdir.data();
    for_octant_size(nd, [&](auto size) {
        constexpr int ND = decltype(size)::value;
        for (int c = 0; c < ncell; ++c) {
            const double* p = psi + c * psi_stride;
            if constexpr (ND > 0)
                accumulate_moments_n<ND>(nmom, op.wY.data(), p, phi + static_cast<std::ptrdiff_t>(c) * nmom);
            else
                accumulate_moments(nd, nmom, op.wY.data(), p, phi + static_cast<std::ptrdiff_t>(c) * nmom);
            double e[4] = {0.0, 0.0, 0.0, 0.0};
            for (int n = 0; n < nd; ++n)
                for (int a = 0; a < 4; ++a) e[a] += wd[4 * n + a] * p[n];
            fluence[c] += e[0];
            for (int a = 0; a < 3; ++a) flux[3 * c + a] += e[1 + a];
        }
    });
}

#if NIMBUS_DOM_HAVE_AVX2

// CB cells at once, NV vectors each: CB x NV accumulators stay in registers; every operator
// row (loaded once) feeds CB cells. One pass adds Σ_r coef[b][r] rows[r] over nrow rows to S
// (kAdd) or stores it (!kAdd); coef of cell b at coef + b * cstride. Stores run in increasing
// address order and the last vector of a cell may spill up to 3 values into the next cell
// (zeros, or that cell's current values when kAdd), which that cell's stores overwrite
// afterwards: S needs room for ncell * nd + 3 values. (One loop per pass: GCC keeps the
// accumulator array in registers only then.)
template <int NV, int CB, bool kAdd>
NIMBUS_DOM_AVX2 inline void source_pass_avx2(int nd, int nrow, const double* rows, const double* coef, int cstride,
                                              double* S) {
    __m256d acc[CB * NV];  // acc[b * NV + v]; a flat, fully unrolled array stays in registers
#pragma GCC unroll 16
    for (int i = 0; i < CB * NV; ++i)
        acc[i] = kAdd ? _mm256_loadu_pd(S + (i / NV) * nd + 4 * (i % NV)) : _mm256_setzero_pd();
    for (int r = 0; r < nrow; ++r) {
        const double* row = rows + r * 4 * NV;
#pragma GCC unroll 16
        for (int b = 0; b < CB; ++b) {
            const __m256d a = _mm256_broadcast_sd(coef + b * cstride + r);
#pragma GCC unroll 16
            for (int v = 0; v < NV; ++v)
                acc[b * NV + v] = _mm256_fmadd_pd(a, _mm256_loadu_pd(row + 4 * v), acc[b * NV + v]);
        }
    }
#pragma GCC unroll 16
    for (int i = 0; i < CB * NV; ++i) _mm256_storeu_pd(S + (i / NV) * nd + 4 * (i % NV), acc[i]);
}

template <int NV, int CB>
NIMBUS_DOM_AVX2 inline void source_block_avx2(int nd, int nl, int nmom, const double* rows, const double* A,
                                               const double* s, double* S) {
    if (nl > 0) {
        source_pass_avx2<NV, CB, false>(nd, nl, rows, A, nl, S);
        source_pass_avx2<NV, CB, true>(nd, nmom, rows + nl * 4 * NV, s, nmom, S);
    } else {
        source_pass_avx2<NV, CB, false>(nd, nmom, rows, s, nmom, S);
    }
}

template <int NV>
NIMBUS_DOM_AVX2 void source_avx2(const OctantSourceOp& op, std::ptrdiff_t ncell, const double* A, const double* s,
                                 double* S) {
    constexpr int CB = NV >= 6 ? 1 : 12 / (NV + 1);  // CB x NV accumulators + NV rows + 1 < 16
    const int nd = op.nd, nl = op.nl, nmom = op.nmom;
    const double* rows = op.rows.data();
    std::ptrdiff_t c = 0;
    for (; c + CB <= ncell; c += CB)
        source_block_avx2<NV, CB>(nd, nl, nmom, rows, nl > 0 ? A + c * nl : nullptr, s + c * nmom, S + c * nd);
    for (; c < ncell; ++c)
        source_block_avx2<NV, 1>(nd, nl, nmom, rows, nl > 0 ? A + c * nl : nullptr, s + c * nmom, S + c * nd);
}

// CB cells at once, MV + (R > 0) + 1 accumulators each: MV full vectors of phi (loaded,
// updated, stored), the R = nmom % 4 tail moments if any, and (fluence, flux x, y, z).
template <int MV, int R, int CB>
NIMBUS_DOM_AVX2 inline void moments_block_avx2(int nd, const double* rows, const double* psi, std::ptrdiff_t ps,
                                               double* phi, double* fluence, double* flux) {
    constexpr int TV = MV + (R > 0 ? 1 : 0) + 1;
    constexpr int nmom = 4 * MV + R;
    __m256d acc[CB * TV];  // acc[b * TV + v]; a flat, fully unrolled array stays in registers
#pragma GCC unroll 16
    for (int i = 0; i < CB * TV; ++i)
        acc[i] = i % TV < MV ? _mm256_loadu_pd(phi + (i / TV) * nmom + 4 * (i % TV)) : _mm256_setzero_pd();
    for (int n = 0; n < nd; ++n) {
        const double* r = rows + n * 4 * TV;
#pragma GCC unroll 16
        for (int b = 0; b < CB; ++b) {
            const __m256d p = _mm256_broadcast_sd(psi + b * ps + n);
#pragma GCC unroll 16
            for (int v = 0; v < TV; ++v) acc[b * TV + v] = _mm256_fmadd_pd(p, _mm256_loadu_pd(r + 4 * v), acc[b * TV + v]);
        }
    }
    for (int b = 0; b < CB; ++b) {
        for (int v = 0; v < MV; ++v) _mm256_storeu_pd(phi + b * nmom + 4 * v, acc[b * TV + v]);
        alignas(32) double t[4];
        if constexpr (R > 0) {
            _mm256_store_pd(t, acc[b * TV + TV - 2]);
            for (int k = 0; k < R; ++k) phi[b * nmom + 4 * MV + k] += t[k];
        }
        _mm256_store_pd(t, acc[b * TV + TV - 1]);
        fluence[b] += t[0];
        for (int a = 0; a < 3; ++a) flux[3 * b + a] += t[1 + a];
    }
}

template <int MV, int R>
NIMBUS_DOM_AVX2 void moments_avx2(const OctantMomentOp& op, int ncell, const double* psi, std::ptrdiff_t ps,
                                  double* phi, double* fluence, double* flux) {
    constexpr int TV = MV + (R > 0 ? 1 : 0) + 1;
    constexpr int CB = TV <= 3 ? 4 : (TV <= 7 ? 2 : 1);
    constexpr int nmom = 4 * MV + R;
    const int nd = op.nd;
    const double* rows = op.rows.data();
    int c = 0;
    for (; c + CB <= ncell; c += CB)
        moments_block_avx2<MV, R, CB>(nd, rows, psi + c * ps, ps, phi + static_cast<std::ptrdiff_t>(c) * nmom,
                                      fluence + c, flux + 3 * c);
    for (; c < ncell; ++c)
        moments_block_avx2<MV, R, 1>(nd, rows, psi + c * ps, ps, phi + static_cast<std::ptrdiff_t>(c) * nmom,
                                     fluence + c, flux + 3 * c);
}

// Compile-time sizes the avx2 path covers (nd <= 36; nmom = 0 or (L+1)² <= 49), beyond them: portable.
inline bool source_dispatch_avx2(const OctantSourceOp& op, std::ptrdiff_t ncell, const double* A, const double* s,
                                 double* S) {
    switch (op.nv) {
        case 1: source_avx2<1>(op, ncell, A, s, S); return true;
        case 2: source_avx2<2>(op, ncell, A, s, S); return true;
        case 3: source_avx2<3>(op, ncell, A, s, S); return true;
        case 4: source_avx2<4>(op, ncell, A, s, S); return true;
        case 5: source_avx2<5>(op, ncell, A, s, S); return true;
        case 6: source_avx2<6>(op, ncell, A, s, S); return true;
        case 7: source_avx2<7>(op, ncell, A, s, S); return true;
        case 8: source_avx2<8>(op, ncell, A, s, S); return true;
        case 9: source_avx2<9>(op, ncell, A, s, S); return true;
        default: return false;
    }
}

inline bool moments_dispatch_avx2(const OctantMomentOp& op, int ncell, const double* psi, std::ptrdiff_t ps,
                                  double* phi, double* fluence, double* flux) {
    switch (op.nmom) {
        case 0: moments_avx2<0, 0>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 1: moments_avx2<0, 1>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 4: moments_avx2<1, 0>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 9: moments_avx2<2, 1>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 16: moments_avx2<4, 0>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 25: moments_avx2<6, 1>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 36: moments_avx2<9, 0>(op, ncell, psi, ps, phi, fluence, flux); return true;
        case 49: moments_avx2<12, 1>(op, ncell, psi, ps, phi, fluence, flux); return true;
        default: return false;
    }
}

#endif

inline bool use_avx2(MomentPath path) {
    if (path == MomentPath::portable) return false;
    return path == MomentPath::avx2 ? avx2_available() : avx2_selected();
}

}  // namespace detail

// S (cells x nd, contiguous) for ncell consecutive cells: A is ncell x nl (unused if nl = 0),
// s ncell x nmom. S must have room for ncell * nd + 3 values (see source_block_avx2).
inline void apply_source(const OctantSourceOp& op, std::ptrdiff_t ncell, const double* A, const double* s, double* S,
                         MomentPath path = MomentPath::automatic) {
#if NIMBUS_DOM_HAVE_AVX2
    if (detail::use_avx2(path) && detail::source_dispatch_avx2(op, ncell, A, s, S)) return;
#endif
    detail::source_portable(op, ncell, A, s, S);
}

// Adds the octant's contribution of ncell consecutive cells (a row): psi of cell c at
// psi + c * psi_stride (nd values), phi ncell x nmom, fluence ncell, flux ncell x 3.
inline void apply_moments(const OctantMomentOp& op, int ncell, const double* psi, std::ptrdiff_t psi_stride,
                          double* phi, double* fluence, double* flux, MomentPath path = MomentPath::automatic) {
#if NIMBUS_DOM_HAVE_AVX2
    if (detail::use_avx2(path) && detail::moments_dispatch_avx2(op, ncell, psi, psi_stride, phi, fluence, flux))
        return;
#endif
    detail::moments_portable(op, ncell, psi, psi_stride, phi, fluence, flux);
}

}  // namespace nimbus::dom
