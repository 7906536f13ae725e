// Ray-march kernels for a view-path-dependent source (view_source.h). Pure apart from the
// source's own pure calls (no MPI, no allocation). The step lattice, the empty-block skips and
// the per-step integration are those of march.h; in addition, per step with rho > 0:
//   C_b += T_b (J_b + rho sigma_s,b H_b) w,   T_b *= e        (w, e: step_weights, march.h)
// where H is the source value of the latest sample point (view_source.h). A rank's piece does
// not know the H left by the pieces in front, so until its first sample point on the lattice
// it accumulates the coefficient of that unknown instead,
//   A_b += T_b rho sigma_s,b w,
// and the compositor adds T_front A_b H_carried (composite.h). H_spec is the value at the
// piece's first step with rho > 0: the carried value when no piece in front had medium.
#pragma once

#include <bit>
#include <cmath>

#include "src/render/march.h"
#include "src/render/view_source.h"

namespace nimbus {

// The view-path state of one piece of a ray.
struct ViewPathState {
    double tau = 0.0, s = 0.0;      // view depths (view_source.h); in: at the piece entry
    double A[kMaxBands] = {};       // coefficient of the carried H (out)
    double H_spec[kMaxBands] = {};  // value at the piece's first step with rho > 0 (out)
    double H[kMaxBands] = {};       // value of the piece's latest sample point (out)
    bool has_spec = false, has_sample = false;
};

// The lattice level of a spacing: k = floor(log2(spacing / ds)) clamped to [0, 20].
inline int sample_level(double spacing, double ds) {
    const double r = spacing / ds;
    if (!(r >= 2.0)) return 0;
    return std::min(20, std::ilogb(r));
}

// View depths over steps [m_begin, m_end) (the same visits and sums as march_steps_source):
// tau += rho ds and s += ds on every step with rho > 0.
// NB as in march_steps_source (the same trilinear arithmetic, hence the same sums).
template <int NB>
void march_depth(const MarchView& v, const RaySteps& r, int m_begin, int m_end, double& tau,
                 double& s) {
    const int nb = NB > 0 ? NB : v.nbands;
    const std::ptrdiff_t nc = 1 + nb;
    const std::ptrdiff_t sx = v.sx, sy = v.sy, sz = v.sz;
    const int bs = 1 << v.block_shift;
    for (int m = m_begin; m < m_end;) {
        double q[3];
        step_midpoint(r, v, m, q);
        const int ix = clamped_cell(q[0], v.n[0]), iy = clamped_cell(q[1], v.n[1]),
                  iz = clamped_cell(q[2], v.n[2]);
        const int bx = (ix - v.owned.lo[0]) >> v.block_shift, by = (iy - v.owned.lo[1]) >> v.block_shift,
                  bz = (iz - v.owned.lo[2]) >> v.block_shift;
        if (!v.occupied[(static_cast<std::ptrdiff_t>(bz) * v.nblocks[1] + by) * v.nblocks[0] + bx]) {
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
        const double cx = q[0] - 0.5, cy = q[1] - 0.5, cz = q[2] - 0.5;
        const int i0 = static_cast<int>(cx + 1.0) - 1, j0 = static_cast<int>(cy + 1.0) - 1,
                  k0 = static_cast<int>(cz + 1.0) - 1;
        const float* p = v.data + (k0 - v.alo[2]) * sz + (j0 - v.alo[1]) * sy + (i0 - v.alo[0]) * sx;
        double smp[NB > 0 ? 1 + NB : 1 + kMaxBands] = {};
        trilinear<NB>(p, sx, sy, sz, nc, cx - i0, cy - j0, cz - k0, smp);
        const double rho = smp[0];
        ++m;
        if (!(rho > 0.0)) continue;
        tau += rho * r.ds;
        s += r.ds;
    }
}

// march_steps<NB, true> plus the view-path source (header comment). sigma_s: per band, 1/m per
// unit density. Returns the number of steps sampled.
template <int NB>
long march_steps_source(const MarchView& v, const RaySteps& r, int m_begin, int m_end, double eps,
                        const ViewRaySource& src, const double* sigma_s, double* C, double* T,
                        ViewPathState& st) {
    const int nb = NB > 0 ? NB : v.nbands;
    const std::ptrdiff_t nc = 1 + nb;
    const std::ptrdiff_t sx = v.sx, sy = v.sy, sz = v.sz;
    const int bs = 1 << v.block_shift;
    const Vec3 w_out = -r.d;
    long samples = 0;
    for (int m = m_begin; m < m_end;) {
        double q[3];
        step_midpoint(r, v, m, q);
        const int ix = clamped_cell(q[0], v.n[0]), iy = clamped_cell(q[1], v.n[1]),
                  iz = clamped_cell(q[2], v.n[2]);
        const int bx = (ix - v.owned.lo[0]) >> v.block_shift, by = (iy - v.owned.lo[1]) >> v.block_shift,
                  bz = (iz - v.owned.lo[2]) >> v.block_shift;
        if (!v.occupied[(static_cast<std::ptrdiff_t>(bz) * v.nblocks[1] + by) * v.nblocks[0] + bx]) {
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
        const double cx = q[0] - 0.5, cy = q[1] - 0.5, cz = q[2] - 0.5;
        const int i0 = static_cast<int>(cx + 1.0) - 1, j0 = static_cast<int>(cy + 1.0) - 1,
                  k0 = static_cast<int>(cz + 1.0) - 1;
        const float* p = v.data + (k0 - v.alo[2]) * sz + (j0 - v.alo[1]) * sy + (i0 - v.alo[0]) * sx;
        double s[NB > 0 ? 1 + NB : 1 + kMaxBands] = {};
        trilinear<NB>(p, sx, sy, sz, nc, cx - i0, cy - j0, cz - k0, s);
        ++samples;
        const int m_here = m++;
        const double rho = s[0];
        if (!(rho > 0.0)) continue;
        // Sample points (view_source.h): the piece's first medium step (H_spec) and the
        // lattice multiples of 2^k.
        // m is a multiple of 2^k iff k <= ctz(m); the cheap bound rules most steps out.
        const int c = m_here == 0 ? 31 : std::countr_zero(static_cast<unsigned>(m_here));
        const double t = r.t_enter + (m_here + 0.5) * r.ds;
        bool aligned = sample_level(src.spacing_bound(st.tau, st.s), r.ds) <= c;
        if (aligned) aligned = sample_level(src.spacing(r.o + r.d * t, st.tau, st.s), r.ds) <= c;
        if (!st.has_spec || aligned) {
            double H[kMaxBands];
            src.sample(r.o + r.d * t, w_out, st.tau, st.s, H);
            if (!st.has_spec) {
                std::copy(H, H + nb, st.H_spec);
                st.has_spec = true;
            }
            if (aligned) {
                std::copy(H, H + nb, st.H);
                st.has_sample = true;
            }
        }
        double Tmax = 0.0, e = 1.0, w = r.ds;
        for (int b = 0; b < nb; ++b) {
            if (b == 0 || !v.uniform_sigma) step_weights(rho * v.sigma_t[b], r.ds, e, w);
            const double ss = rho * sigma_s[b];
            if (st.has_sample) {
                C[b] += T[b] * (s[1 + b] + ss * st.H[b]) * w;
            } else {
                C[b] += T[b] * s[1 + b] * w;
                st.A[b] += T[b] * ss * w;
            }
            T[b] *= e;
            Tmax = std::max(Tmax, T[b]);
        }
        st.tau += rho * r.ds;
        st.s += r.ds;
        if (Tmax < eps) break;
    }
    return samples;
}

}  // namespace nimbus
