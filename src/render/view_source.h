// ViewRaySource: an optional radiance source that depends on the VIEW PATH, not only on the
// cell (e.g. the PSF multiple-scattering lookup of Premoze et al. 2004 §5, whose blur width
// depends on the scattering count l1 accumulated along the view ray). A model provides it in
// RenderInputs::view_source; the ray caster then adds, per step of constant coefficients,
//   J_b += rho sigma_s,b H_b,            (W/(m³ sr); H_b is a radiance, W/(m² sr))
// with H_b held constant between SAMPLE POINTS that the source spaces along the ray.
//
// View depths (exact on the ray's step lattice, march.h): at step m, before the step,
//   tau_view = Σ_{steps m' < m, rho > 0} rho ds   (∫ rho ds from the domain entry; metres x density)
//   s_view   = Σ_{steps m' < m, rho > 0} ds       (geometric length inside the medium, metres)
// In the distributed ray caster a rank marches only its piece of a ray; the depths at its entry
// come from the ranks in front (a per-pixel prepass with an exclusive scan in visibility order).
//
// Sample points (a function of the global lattice, the step's position and its view depths
// only, hence the same for every decomposition): the first step with rho > 0, and every step m
// with rho > 0 where m is a multiple of 2^k, k = floor(log2(spacing(x, tau_view, s_view) / ds))
// clamped to [0, 20], taken as the larger of the levels of spacing_bound(tau_view, s_view) (a
// cheap floor, meant to bound spacing from below) and spacing(x, ...): the marcher skips the
// spacing call on steps that the floor already rules out.
#pragma once

#include <limits>

#include "src/core/box.h"
#include "src/core/decomposition.h"
#include "src/core/vec3.h"

namespace nimbus {

class ViewRaySource {
public:
    virtual ~ViewRaySource() = default;
    // Collective over d.comm(). Called once per render, after load balancing, with the global
    // cells whose steps this rank marches (march_box); the source makes sample() valid on
    // every point whose trilinear stencil lies in march_box grown by one cell.
    virtual void prepare(const Box& march_box, const Decomposition& d) = 0;
    // Distance (metres) to aim for between sample points at step midpoint x. Pure.
    virtual double spacing(const Vec3& x, double tau_view, double s_view) const = 0;
    // A lower bound of spacing() over all x (0 is always valid). Pure, cheap.
    virtual double spacing_bound(double /*tau_view*/, double /*s_view*/) const { return 0.0; }
    // H_b (one value per band) at world point x for radiance travelling toward w_out (unit,
    // toward the camera). Pure; no MPI, no allocation.
    virtual void sample(const Vec3& x, const Vec3& w_out, double tau_view, double s_view,
                        double* H) const = 0;
    // An upper bound of |H_b| over every sample() of this render, per band (nbands values), for
    // the ray caster's early termination (march.h); the same on every rank. +inf (the default:
    // no bound known) lets no ray stop before its transmittance underflows to 0.
    virtual void radiance_bound(int nbands, double* H) const {
        for (int b = 0; b < nbands; ++b) H[b] = std::numeric_limits<double>::infinity();
    }
};

}  // namespace nimbus
