// The PSF multiple-scattering source (Premoze et al. 2004 §5, Algorithms 1 and 2) as a
// view-path source of the ray caster (src/render/view_source.h).
//
// Preprocessing (collective): per light term l (sun, sky bins) and per group of bands sharing
// sigma_t, the light volume T_l = exp(-sigma_t tau_rho_l) (E0 is applied at lookup) and its
// pyramid (pyramid.h); per light the depths to the light tau_rho_l (l2 = sigma_s tau_rho_l) and
// the path length inside the medium s2_l = ∫ [rho > 0] ds (the light pass run on the indicator
// of the medium).
//
// Per view sample x (view depths tau_view, s_view: view_source.h), band b, light l:
//   l = sigma_s (tau_view + tau_rho_l(x)),  S = s_view + s2_l(x)                 (Alg. 2 lines 1-7)
//   w = sqrt(eq. 18 (<θ²>, l, S, a/b))                                           (line 8)
//   L = E0_l [T_l]_w(x), linear in w between the two pyramid levels around w     (line 9)
//   H_b = Σ_l L exp(-α_c Δθ²/l) P_MS(l, Δθ),  Δθ = angle(w_l, w_out)            (lines 10-13)
// The ray caster adds rho sigma_s H_b per unit length and applies the view-leg transmittance;
// the light volume carries the light-leg transmittance, so together they are exactly the
// paper's exp(-(c/b) l) = exp(-∫ c ds) along the two-segment path (c/b = 1/albedo is uniform).
// Sample spacing (Fig. 9): step_growth × max(2h, 2w), the diameter of the blur sphere projected
// onto the view ray (perpendicular case), with w of the sun's (first light term's) full path at
// the step, l = sigma_s (tau_view + tau_rho_0(x)), S = s_view + s2_0(x), the smallest over the
// bands that scatter (so the points depend neither on the bands' order nor on a band that does
// not scatter), and never finer than 2h = w_1, the blur width of the finest blurred pyramid
// level; the cheap floor uses w of the view leg alone. Both depend only on the step and its view depths,
// which keeps the sample points independent of the decomposition. step_growth = 0 samples
// every step.
#pragma once

#include <memory>
#include <vector>

#include "solvers/psf/blur_width.h"
#include "solvers/psf/pyramid.h"
#include "src/model/model.h"
#include "src/model/options.h"
#include "src/render/view_source.h"

namespace nimbus::psf {

// Ghost layers of the level-0 light volume (the pyramid's first blur reaches 3 cells).
inline constexpr int kLevel0Ghost = 3;

// What the model needs of the decomposition: slabs along z, each at least kLevel0Ghost layers
// thick (the halo exchange fills ghosts from the adjacent rank only). Throws Error on every rank
// alike; run by the model's pre-flight check and again by PsfSource.
void check_decomposition(const Decomposition& d);

// What the model needs of the lights: one light volume per light term and band of distinct
// sigma_t, at most 64 in all. Throws Error (the same on every rank); run by the pre-flight check
// (so `nimbus info` says it too) and again by PsfSource.
void check_light_volumes(int nlights, const std::vector<BandOptics>& bands);

struct BandPsf {
    double sigma_s = 0.0;   // 1/m per unit density
    double a_over_b = 0.0;  // absorption / scattering
    double theta2 = 0.0;    // <θ²> (eq. 2)
    int group = 0;          // light-volume component group (bands sharing sigma_t)
    MsPhase phase;
};

class PsfSource final : public ViewRaySource {
public:
    // Collective over ctx.decomp.comm(): the light volumes, their pyramid and the light depths.
    PsfSource(const SolveContext& ctx, const PsfOptions& opt);

    void prepare(const Box& march_box, const Decomposition& d) override;
    double spacing(const Vec3& x, double tau_view, double s_view) const override;
    double spacing_bound(double tau_view, double s_view) const override;
    void sample(const Vec3& x, const Vec3& w_out, double tau_view, double s_view, double* H) const override;
    // H_b <= Σ_l E0_l,b max P_MS weight of band b: sample()'s blurred transmittance is a convex
    // combination of pyramid values, each an average of exp(-sigma_t tau) <= 1.
    void radiance_bound(int nbands, double* H) const override;

    // Collective. The equivalent fluence_diffuse (README): at each owned cell with rho > 0, the
    // PSF radiance of a path with no view leg (l = l2, S = s2) integrated over all directions,
    //   fluence_b = Σ_l E0_l [T_l]_w ∫ exp(-α_c θ²/l2) P_MS(l2, θ) dω = Σ_l E0_l [T_l]_w G(l2),
    //   l2 = sigma_s tau_rho_l, w = sqrt(eq. 18 (l2, s2_l)).
    // out: one field per band on d.local() (+1 ghost, exchanged).
    void fluence(const Medium& m, const Decomposition& d, std::vector<Field<double>>& out);

    const LightPyramid& pyramid() const { return pyramid_; }

    // [T_l]_w for component c (= light * groups + group) at x; w in metres. Needs prepare().
    double lookup(const Vec3& x, double w, int c) const;

private:
    double finest_spacing(double tau, double S) const;  // spacing()'s rule at depth tau, path S
    std::vector<DirectionalLight> lights_;
    // Level k of the pyramid at x into out (all components); level 0 as exp(-sigma_t tau_rho_l)
    // from the interpolated depths (so level 0 is never gathered for the march box).
    void level_at(int k, const Vec3& x, const float* depth, float* out) const;

    std::vector<BandPsf> bands_;
    std::vector<double> group_sigma_;  // sigma_t per light-volume group
    int ngroups_ = 1;
    double step_growth_ = 1.0;
    double h_ = 1.0;  // cell edge: the finest sample spacing (x step_growth)
    LightPyramid pyramid_;
    PyramidLevel depth_;  // level-0 layout, components [tau_rho_l, s2_l] per light
    // prepare(): every level (and the depths) over the march box.
    std::vector<Field<float>> gathered_;
    std::vector<const Field<float>*> view_;
    Field<float> depth_gathered_;
    const Field<float>* depth_view_ = nullptr;
};

}  // namespace nimbus::psf
