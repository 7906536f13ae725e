// The ray-march kernel: integrates one rank's piece of a view ray through its ViewVolume.
// Pure (no MPI, no allocation); the driver (raycaster.cpp) sets up the segment.
//
// Step lattice. A view ray's chord through the DOMAIN [t_enter, t_exit] is cut into n equal
// steps of length ds <= render.step * h; step m is represented by its midpoint
//   x_m = o + (t_enter + (m + 1/2) ds) d
// and belongs to the rank owning the cell that contains x_m (clamped into the domain). The
// lattice and the owner test depend only on the camera and the global grid, so the ranks'
// pieces partition every ray exactly and the image does not depend on the decomposition:
// a trilinear sample at x_m needs only its cell and one neighbour layer (the ghost layer).
//
// Per step, kappa_b and J_b are the trilinear samples at x_m (with split lights, view_volume.h,
// J_b = Jd_b + A_b e^{ln T_b} of the trilinear Jd, A and ln T), held constant over the step and
// integrated exactly (Max 1995 §4 eq. 7 on one step of constant coefficients):
//   C_b += T_b (J_b / kappa_b) (1 - e^{-kappa_b ds})  (-> T_b J_b ds as kappa_b ds -> 0),
//   T_b *= e^{-kappa_b ds}.
// Without attenuation (emission only, Max 1995 §3 eq. 5): C_b += J_b ds, T_b = 1.
// The march jumps over empty occupancy blocks without sampling.
//
// Early termination, bounded per pixel. Let S_b be the largest of |J_b| / max(kappa_b, 1/L)
// over the cells (L: the domain's diagonal, the longest chord) and of the background's radiance.
// A trilinear sample has |J| <= S (kappa + 1/L) (the same convex combination of both), so
// behind a step with transmittance T_b the rest of the ray adds at most
//   Σ T' |J| w <= S Σ T' (1 - e) + S T_b L/L <= 2 S T_b   (w = (1 - e)/kappa <= ds),
// the background included (T_end L_bg <= T_end S). Stopping there leaves out the rest of this
// piece and composites whatever lies behind it with T_b instead of the true, smaller T: two
// terms each of size <= 2 T_b S_b and of the same sign when J >= 0 everywhere, so the error is
// at most B_b T_b with B_b = 2 S_b, or 4 S_b when some J < 0 (the P1 in-scatter of a flux
// pointing away from the camera). MarchView::radiance_bound holds B_b. The march stops once,
// for every band,
//   T_b < eps   and   T_b B_b <= eps C_b,
// which moves the pixel by at most eps of its radiance (and alpha = 1 - T by < eps). A piece
// marched by one rank of many knows neither the C nor the T in front of it, but the pixel's
// error is then at most T_front T_b B_b <= eps T_front C_b, and those terms sum to eps times
// the pixel's radiance (its positive contributions, if J < 0 somewhere): the bound holds on
// every decomposition, so images on different rank counts agree to 2 eps per pixel, plus
// float32 rounding. The first test alone, T_b < eps, let a dim surface in front of a bright
// source, as in scenes/duct.toml, lose or gain up to 20% by rank count.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

#include "src/core/box.h"
#include "src/core/vec3.h"

namespace nimbus {

// Raw, read-only view of a ViewVolume for the inner loop.
struct MarchView {
    const float* data = nullptr;     // element of allocated-box cell (alo) component 0
    std::ptrdiff_t sx = 0, sy = 0, sz = 0;  // strides between neighbouring cells
    Int3 alo{0, 0, 0};               // low corner of the allocated box (owned - 1)
    Int3 n{0, 0, 0};                 // global cells per axis
    Box owned;
    Vec3 origin;                     // world position of the grid's low corner
    double h = 1.0, inv_h = 1.0;
    const std::uint8_t* occupied = nullptr;
    Int3 nblocks{0, 0, 0};
    int block_shift = 3;
    int nbands = 1;
    const double* sigma_t = nullptr;
    bool uniform_sigma = false;      // all bands share sigma_t: one exponential per step
    const double* radiance_bound = nullptr;  // B_b per band (early termination, header comment)
    int ncomp = 2;                   // floats per cell
    bool split_lights = false;       // cells hold [rho, Jd.., A.., ln T..] (view_volume.h)
    int a_offset = 0, log_t_offset = 0;
};

// Early termination (header comment): whether what lies behind a piece with C and T can move
// the pixel by no more than eps of its radiance, in every band.
inline bool negligible_behind(const MarchView& v, int nb, double eps, const double* C, const double* T) {
    for (int b = 0; b < nb; ++b)
        if (!(T[b] < eps) || T[b] * v.radiance_bound[b] > eps * C[b]) return false;
    return true;
}

// One ray's step lattice; o, d world position and unit direction, inv_d = 1/d per axis (inf for 0).
struct RaySteps {
    Vec3 o, d, inv_d;
    double t_enter = 0, ds = 0;
    int n = 0;  // steps over the domain chord
};

// Continuous cell coordinates (x_m - origin) / h of step m's midpoint.
inline void step_midpoint(const RaySteps& r, const MarchView& v, int m, double q[3]) {
    const double t = r.t_enter + (m + 0.5) * r.ds;
    q[0] = (r.o.x + t * r.d.x - v.origin.x) * v.inv_h;
    q[1] = (r.o.y + t * r.d.y - v.origin.y) * v.inv_h;
    q[2] = (r.o.z + t * r.d.z - v.origin.z) * v.inv_h;
}

// The cell containing q, clamped into the domain.
inline int clamped_cell(double q, int n) {
    const int i = q < 0.0 ? -1 : static_cast<int>(q);
    return std::clamp(i, 0, n - 1);
}

// Whether step m's midpoint lies in a cell of `cells` (cells clamped into the domain). With
// cells = the rank's owned box this is the ownership test that partitions every ray.
inline bool step_in(const RaySteps& r, const MarchView& v, int m, const Box& cells) {
    double q[3];
    step_midpoint(r, v, m, q);
    for (int a = 0; a < 3; ++a) {
        const int c = clamped_cell(q[a], v.n[a]);
        if (c < cells.lo[a] || c >= cells.hi[a]) return false;
    }
    return true;
}

// The most bands march_steps integrates with a run-time band count (NB = 0).
inline constexpr int kMaxBands = 16;

// Trilinear interpolation of the nc values of the 8 cells whose lowest corner is p, weights
// (fx, fy, fz) along x, y, z. NB = 3 (4 floats per cell) runs four lanes at once.
using f4 = float __attribute__((vector_size(16)));

// trilinear<3>'s four lanes: the 4 floats at p of the 8 cells, weights (wx, wy, wz).
inline f4 trilinear4(const float* p, std::ptrdiff_t sx, std::ptrdiff_t sy, std::ptrdiff_t sz, float wx, float wy,
                     float wz) {
    auto ld = [p](std::ptrdiff_t off) {
        f4 x;
        std::memcpy(&x, p + off, sizeof(x));
        return x;
    };
    const f4 c00 = ld(0), c10 = ld(sy), c01 = ld(sz), c11 = ld(sz + sy);
    const f4 a00 = c00 + wx * (ld(sx) - c00), a10 = c10 + wx * (ld(sy + sx) - c10);
    const f4 a01 = c01 + wx * (ld(sz + sx) - c01), a11 = c11 + wx * (ld(sz + sy + sx) - c11);
    const f4 b0 = a00 + wy * (a10 - a00), b1 = a01 + wy * (a11 - a01);
    return b0 + wz * (b1 - b0);
}

template <int NB>
inline void trilinear(const float* p, std::ptrdiff_t sx, std::ptrdiff_t sy, std::ptrdiff_t sz,
                      std::ptrdiff_t nc, double fx, double fy, double fz, double* s) {
    if constexpr (NB == 3) {
        const f4 r = trilinear4(p, sx, sy, sz, static_cast<float>(fx), static_cast<float>(fy), static_cast<float>(fz));
        for (int c = 0; c < 4; ++c) s[c] = r[c];
    } else {
        for (std::ptrdiff_t c = 0; c < nc; ++c) {
            const double a00 = p[c] + fx * (p[c + sx] - p[c]);
            const double a10 = p[c + sy] + fx * (p[c + sy + sx] - p[c + sy]);
            const double a01 = p[c + sz] + fx * (p[c + sz + sx] - p[c + sz]);
            const double a11 = p[c + sz + sy] + fx * (p[c + sz + sy + sx] - p[c + sz + sy]);
            const double b0 = a00 + fy * (a10 - a00), b1 = a01 + fy * (a11 - a01);
            s[c] = b0 + fz * (b1 - b0);
        }
    }
}

// One step of constant kappa over length ds: e = e^{-kappa ds} and w = (1 - e)/kappa
// (-> ds as kappa -> 0), so that C += T J w and T *= e. A series below kappa ds = 1e-4 keeps
// full relative precision there.
inline void step_weights(double kappa, double ds, double& e, double& w) {
    const double x = kappa * ds;
    if (x < 1e-4) {
        const double one_minus_e = x * (1.0 - x * (0.5 - x * (1.0 / 6.0)));
        e = 1.0 - one_minus_e;
        w = ds * (1.0 - x * (0.5 - x * (1.0 / 6.0)));
    } else {
        e = std::exp(-x);
        w = (1.0 - e) / kappa;
    }
}

// e^x for x in [-87, 0] (the split lights' ln T, view_volume.h; x is clamped to it, and e^-87 =
// 1.6e-38 is float's smallest normal number: 2^n below it has no float) to 3e-7 relative,
// four lanes at once: 2^n e^r with n = x / ln 2 rounded (by adding 1.5 x 2^23), r = x - n ln 2
// (ln 2 in two parts, Cody and Waite) in [-ln 2 / 2, ln 2 / 2] and e^r by its Taylor polynomial
// to r^6 (remainder below (ln 2 / 2)^7 / 7! = 1.3e-7). Test: RenderMarch.ExpOfLogTransmittance.
inline constexpr float kMinLogT = -87.0f;
inline f4 exp_log_t(f4 x) {
    using i4 = int __attribute__((vector_size(16)));
    const f4 lo = {kMinLogT, kMinLogT, kMinLogT, kMinLogT}, hi = {0.0f, 0.0f, 0.0f, 0.0f};
    x = x < lo ? lo : x;
    x = x > hi ? hi : x;
    constexpr float kRound = 12582912.0f;  // 1.5 x 2^23
    const f4 n = (x * 1.44269504f + kRound) - kRound;
    const f4 r = (x - n * 0.693359375f) - n * -2.12194440e-4f;
    const f4 p = 1.0f + r * (1.0f + r * (0.5f + r * (1.0f / 6 + r * (1.0f / 24 + r * (1.0f / 120 + r * (1.0f / 720))))));
    const i4 bits = (__builtin_convertvector(n, i4) + 127) << 23;
    return p * std::bit_cast<f4>(bits);
}

// The trilinear sample s[0] = rho, s[1 + b] = J_b of the 8 cells whose lowest corner is p
// (split lights: J_b = Jd_b + A_b e^{ln T_b}, view_volume.h).
template <int NB>
inline void sample_cells(const MarchView& v, const float* p, double fx, double fy, double fz, double* s) {
    const int nb = NB > 0 ? NB : v.nbands;
    if constexpr (NB == 3) {
        const float wx = static_cast<float>(fx), wy = static_cast<float>(fy), wz = static_cast<float>(fz);
        f4 r = trilinear4(p, v.sx, v.sy, v.sz, wx, wy, wz);
        if (v.split_lights) {  // cells [rho, Jd_0..2 | A_0..2, 0 | ln T_0..2, 0]
            const f4 a = trilinear4(p + 4, v.sx, v.sy, v.sz, wx, wy, wz);
            const f4 at = a * exp_log_t(trilinear4(p + 8, v.sx, v.sy, v.sz, wx, wy, wz));
            r += f4{0.0f, at[0], at[1], at[2]};
        }
        for (int c = 0; c < 4; ++c) s[c] = r[c];
    } else {
        trilinear<NB>(p, v.sx, v.sy, v.sz, v.ncomp, fx, fy, fz, s);
        if (v.split_lights)
            for (int b = 0; b < nb; ++b) {
                const float x = static_cast<float>(s[v.log_t_offset + b]);
                s[1 + b] += s[v.a_offset + b] * exp_log_t(f4{x, x, x, x})[0];
            }
    }
}

// The one stepping loop of the ray caster: visits the steps [m_begin, m_end) in order, skipping
// empty occupancy blocks without sampling; for every other step it takes the trilinear sample
// s[0] = rho, s[1 + b] = J_b at the step midpoint and calls visit(m, s), which returns false to
// stop the march (early termination). NB as in march_steps. Returns the number of steps sampled.
template <int NB, class Visit>
long for_each_sample(const MarchView& v, const RaySteps& r, int m_begin, int m_end, Visit&& visit) {
    const std::ptrdiff_t sx = v.sx, sy = v.sy, sz = v.sz;
    const int bs = 1 << v.block_shift;
    long samples = 0;
    for (int m = m_begin; m < m_end;) {
        double q[3];
        step_midpoint(r, v, m, q);
        const int ix = clamped_cell(q[0], v.n[0]), iy = clamped_cell(q[1], v.n[1]),
                  iz = clamped_cell(q[2], v.n[2]);
        const int bx = (ix - v.owned.lo[0]) >> v.block_shift, by = (iy - v.owned.lo[1]) >> v.block_shift,
                  bz = (iz - v.owned.lo[2]) >> v.block_shift;
        if (!v.occupied[(static_cast<std::ptrdiff_t>(bz) * v.nblocks[1] + by) * v.nblocks[0] + bx]) {
            // Leave the empty block: first midpoint at or beyond the ray's exit from it.
            double t_out = std::numeric_limits<double>::infinity();
            const int b3[3] = {bx, by, bz};
            for (int a = 0; a < 3; ++a) {
                if (r.d[a] == 0.0) continue;
                const int face = r.d[a] > 0 ? std::min(v.owned.lo[a] + (b3[a] + 1) * bs, v.owned.hi[a])
                                            : v.owned.lo[a] + b3[a] * bs;
                t_out = std::min(t_out, (v.origin[a] + face * v.h - r.o[a]) * r.inv_d[a]);
            }
            const double next = (t_out - r.t_enter) / r.ds - 0.5;
            m = next >= m_end ? m_end : std::max(m + 1, static_cast<int>(std::ceil(next)));
            continue;
        }
        // Trilinear weights between cell centres (cell i's centre at q = i + 1/2).
        const double cx = q[0] - 0.5, cy = q[1] - 0.5, cz = q[2] - 0.5;
        const int i0 = static_cast<int>(cx + 1.0) - 1, j0 = static_cast<int>(cy + 1.0) - 1,
                  k0 = static_cast<int>(cz + 1.0) - 1;
        const float* p = v.data + (k0 - v.alo[2]) * sz + (j0 - v.alo[1]) * sy + (i0 - v.alo[0]) * sx;
        double s[NB == 3 ? 4 : 1 + 3 * (NB > 0 ? NB : kMaxBands)] = {};
        sample_cells<NB>(v, p, cx - i0, cy - j0, cz - k0, s);
        ++samples;
        if (!visit(m++, static_cast<const double*>(s))) break;
    }
    return samples;
}

// Integrates steps [m_begin, m_end) (all owned by this rank). C, T: nbands values each,
// in/out (start with C = 0, T = 1). NB > 0 fixes the band count at compile time, NB = 0 reads
// v.nbands (at most kMaxBands). Returns the number of steps sampled.
template <int NB, bool kAttenuate>
long march_steps(const MarchView& v, const RaySteps& r, int m_begin, int m_end, double eps,
                 double* C, double* T) {
    const int nb = NB > 0 ? NB : v.nbands;
    return for_each_sample<NB>(v, r, m_begin, m_end, [&](int, const double* s) {
        const double rho = s[0];
        if constexpr (kAttenuate) {
            if (!(rho > 0.0)) return true;  // nothing to attenuate or emit (J = 0 where rho = 0)
            double Tmax = 0.0, e = 1.0, w = r.ds;
            for (int b = 0; b < nb; ++b) {
                if (b == 0 || !v.uniform_sigma) step_weights(rho * v.sigma_t[b], r.ds, e, w);
                C[b] += T[b] * s[1 + b] * w;
                T[b] *= e;
                Tmax = std::max(Tmax, T[b]);
            }
            return !(Tmax < eps) || !negligible_behind(v, nb, eps, C, T);
        } else {
            for (int b = 0; b < nb; ++b) C[b] += s[1 + b] * r.ds;
            return true;
        }
    });
}

}  // namespace nimbus
