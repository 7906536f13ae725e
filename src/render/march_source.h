// Ray-march kernels for a view-path-dependent source (view_source.h). Pure apart from the
// source's own pure calls (no MPI, no allocation). Both run on march.h's one stepping loop
// (for_each_sample: the step lattice, the empty-block skips, the trilinear samples) with the
// per-step integration of march_steps; in addition, per step with rho > 0:
//   C_b += T_b (J_b + rho sigma_s,b H_b) w,   T_b *= e        (w, e: step_weights, march.h)
// where H is the source value of the latest sample point (view_source.h). A rank's piece does
// not know the H left by the pieces in front, so until its first sample point on the lattice
// it accumulates the coefficient of that unknown instead,
//   A_b += T_b rho sigma_s,b w,
// and the compositor adds T_front A_b H_carried (composite.h). H_spec is the value at the
// piece's first step with rho > 0: the carried value when no piece in front had medium.
// Early termination is march.h's per-pixel rule, T_b < eps and T_b B_b <= eps C_b, with B_b
// counting the source (finish_radiance_bound): S_b grows by a_b H_max,b (the step's J_b +
// rho sigma_s,b H_b over max(kappa_b, 1/L) is at most the cell term plus a_b H_max,b), and B_b
// by one S_b: a piece cut short may hand the pieces behind it another H (its last sample),
// whose coefficient T_cut A_b <= T_cut a_b changes the pixel by at most T_cut a_b H_max,b. C
// leaves out the carried terms A_b H (not known here, >= 0 when H >= 0), which only makes the
// test stricter.
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

// View depths over steps [m_begin, m_end) (the same visits and sums as march_steps_source,
// without its early termination: behind that point the pieces weigh less than eps):
// tau += rho ds and s += ds on every step with rho > 0.
// NB as in march_steps_source (the same trilinear arithmetic, hence the same sums).
template <int NB>
void march_depth(const MarchView& v, const RaySteps& r, int m_begin, int m_end, double& tau,
                 double& s) {
    for_each_sample<NB>(v, r, m_begin, m_end, [&](int, const double* smp) {
        if (smp[0] > 0.0) {
            tau += smp[0] * r.ds;
            s += r.ds;
        }
        return true;
    });
}

// march_steps<NB, true> plus the view-path source (header comment). sigma_s: per band, 1/m per
// unit density. Returns the number of steps sampled.
template <int NB>
long march_steps_source(const MarchView& v, const RaySteps& r, int m_begin, int m_end, double eps,
                        const ViewRaySource& src, const double* sigma_s, double* C, double* T,
                        ViewPathState& st) {
    const int nb = NB > 0 ? NB : v.nbands;
    const Vec3 w_out = -r.d;
    return for_each_sample<NB>(v, r, m_begin, m_end, [&](int m_here, const double* s) {
        const double rho = s[0];
        if (!(rho > 0.0)) return true;
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
        return !(Tmax < eps) || !negligible_behind(v, nb, eps, C, T);
    });
}

}  // namespace nimbus
