// Angular discretization of the light propagation maps (Fattal 2009 §3.1-3.3). Pure geometry,
// no MPI.
//
// The sphere is split into the six cube faces Ω^{±X}, Ω^{±Y}, Ω^{±Z} (cubic cells). A face
// (axis a, sign s) is parameterized by the tangents (t_u, t_v) = (ω_u/|ω_a|, ω_v/|ω_a|) in
// [-1, 1]², with in-plane axes (u, v) = (y, z), (x, z), (x, y) for a = x, y, z (so v is z for
// the X and Y maps: the slab axis that they cross). Two nested partitions of each face:
//   - map bins n: p x p equal squares in (t_u, t_v); the map direction is the square's centre
//     (t_u = -1 + (2i+1)/p), uniform on the cube face as in the paper;
//   - coarse bins m of the unpropagated field U: k x k squares; p % k == 0, so every map bin
//     lies in exactly one coarse bin of its own face (the paper's nesting rule).
// Solid angles are exact: a rectangle [x1,x2]x[y1,y2] on the plane at distance 1 subtends
//   Ω = G(x2,y2) - G(x1,y2) - G(x2,y1) + G(x1,y1),   G(x, y) = atan(x y / sqrt(1 + x² + y²)),
// so Σ_n |Ω^n| = Σ_m |Ω^m| = 4π to round-off.
//
// Form factors (§3.3): P^{n,m} = (1/|Ω^n|) ∫_{Ω^n} ∫_{Ω^m} p(ω·ω') dω dω' — the fraction of
// the light travelling in map bin n that a scattering sends into coarse bin m (the paper's
// F^{n,m} for a phase function normalized to 1, divided by |Ω^n|). Computed by quadrature on
// squares weighted by their exact solid angle, refined toward the HG peak (hg_over_face_rectangle),
// then each row is normalized to Σ_m = 1, so scattering conserves energy exactly for any g; for
// g = 0 the rows are |Ω^m|/4π exactly.
#pragma once

#include <array>
#include <map>
#include <vector>

#include "src/core/vec3.h"

namespace nimbus::lpm {

// Face f = 2a + (s < 0): axis a, sign s. In-plane axes of axis a.
inline int face_axis(int f) { return f / 2; }
inline int face_sign(int f) { return f % 2 == 0 ? 1 : -1; }
inline int u_axis(int a) { return a == 0 ? 1 : 0; }
inline int v_axis(int a) { return a == 2 ? 1 : 2; }

// Exact solid angle of the face rectangle [x1,x2] x [y1,y2] (tangent coordinates).
double face_solid_angle(double x1, double x2, double y1, double y2);

// The unit direction of face f at tangents (tu, tv).
Vec3 face_direction(int f, double tu, double tv);

// ∫ p_HG(ω·w) dω over the rectangle [x1,x2] x [y1,y2] of face f, for light travelling along the
// unit vector w: squares refined toward the lobe's peak (a 2 x 2 Gauss rule each), so the
// cost grows like log(1/(1-|g|)) and the whole sphere integrates to 1 within 2e-5 for |g| up to
// 0.9999.
double hg_over_face_rectangle(double g, const Vec3& w, int f, double x1, double x2, double y1, double y2);

class Angular {
public:
    Angular(int p, int k);

    int p() const { return p_; }
    int k() const { return k_; }
    int map_bins() const { return 6 * p_ * p_; }    // n = f p² + iv p + iu
    int coarse_bins() const { return 6 * k_ * k_; }  // m = f k² + jv k + ju
    double tangent(int i) const { return -1.0 + (2.0 * i + 1.0) / p_; }  // centre of map bin i

    const Vec3& direction(int n) const { return dir_[static_cast<size_t>(n)]; }       // ray direction
    const Vec3& mean_direction(int n) const { return mean_[static_cast<size_t>(n)]; }  // (1/|Ω^n|) ∫ ω dω
    double solid_angle(int n) const { return omega_[static_cast<size_t>(n)]; }
    double coarse_solid_angle(int m) const { return coarse_omega_[static_cast<size_t>(m)]; }
    int coarse_of(int n) const { return coarse_of_[static_cast<size_t>(n)]; }
    int coarse_bin_of(const Vec3& w) const;  // the coarse bin containing direction w

    // P^{n,m} for HG asymmetry g: row-major [map_bins()][coarse_bins()], rows sum to 1.
    // Computed once per g and kept (bands sharing g share them).
    const std::vector<double>& form_factors(double g) const;
    // ∫_{Ω^m} p(ω·w) dω for a collimated beam travelling along unit w (the first-scatter
    // source's angular split), normalized to Σ_m = 1. Kept per (g, w) like form_factors.
    const std::vector<double>& beam_factors(double g, const Vec3& w) const;

private:
    // ∫_{Ω^m} p(ω·w) dω for every coarse bin m (unnormalized).
    std::vector<double> hg_over_coarse_bins(double g, const Vec3& w) const;
    std::vector<double> compute_form_factors(double g) const;
    std::vector<double> compute_beam_factors(double g, const Vec3& w) const;

    int p_, k_;
    mutable std::map<double, std::vector<double>> form_factors_;  // by g
    mutable std::map<std::array<double, 4>, std::vector<double>> beam_factors_;  // by (g, w)
    std::vector<Vec3> dir_, mean_;
    std::vector<double> omega_, coarse_omega_;
    std::vector<int> coarse_of_;
};

}  // namespace nimbus::lpm
