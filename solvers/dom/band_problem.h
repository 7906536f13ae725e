// The discrete-ordinates problem of one band: delta-M scaled optics, the first-collision
// source of every light term and an optional isotropic volume emission, on the rank's box.
//
// Delta-M (Wiscombe 1977; src/physics/angular_moments.h): with f = g^{L+1} (0 without delta-M)
//   kappa* = (1 - a f) kappa,  kappa* a* = (1 - f) kappa a,  chi*_l = (g^l - f)/(1 - f).
// The scaled problem is solved consistently, INCLUDING its collimated beam: the beam of light
// term l is attenuated by kappa* (T*_l = exp(-(1 - a f) sigma_t tau_rho_l), exact from the light
// pass's optical depth), and its first-collision source is
//   Q*(x, Ω) = kappa* a* E0_l T*_l p*_L(Ω·w_l)                         (DESIGN §1, scaled)
// with p*_L the truncated scaled series, renormalized so that Σ_n w_n p*_L(Ω_n·w_l) = 1
// (the quadrature then scatters exactly the beam power). The forward peak f of every
// scattering event is light that kept its direction; for the beam this is E0_l (T*_l - T_l)
// travelling along w_l. It has been scattered, so it is diffuse light in DESIGN's split: it
// is added to fluence_diffuse and flux_diffuse (forward_fluence/forward_flux below), exactly,
// without any ray effect, as the cell's mean of T*_l - T_l (LightTransport::forward_peak_mean,
// the mean that the source's <T*> is). With delta-M off (or g = 0) it is zero.
//
// Ownership: plain values. Fields on d.local() without ghosts unless stated.
#pragma once

#include <array>
#include <vector>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/transport_sweep.h"
#include "src/core/field.h"
#include "src/model/model.h"
#include "src/physics/angular_moments.h"
#include "src/scene/medium.h"

namespace nimbus::dom {

struct BandProblem {
    double h = 1.0;
    LegendrePhase phase;                 // chi*_l and f
    Field<double> kappa;                 // kappa* (1/m)
    Field<double> sigma_s;               // kappa* a* (1/m)
    Field<double> sigma_a;               // kappa (1 - a) (1/m), unchanged by delta-M
    Field<double> kappa_tr;              // kappa (1 - a g) = kappa* (1 - a* chi*_1) (1/m)
    Field<double> emission;              // isotropic volume source (W/m³/sr), 1 component
    int nl = 0;
    Field<double> amp;                   // nl components: kappa* a* E0_l T*_l (W/m³)
    std::array<std::vector<double>, 8> light_phase;  // per octant nl x nd: p*_L(Ω_n·w_l), renormalized
    Field<double> forward_fluence;       // Σ_l E0_l <T*_l - T_l> (W/m²), cell means
    Field<double> forward_flux;          // Σ_l E0_l <T*_l - T_l> w_l, 3 components
};

// Where p's sweep source can be nonzero (SourceRows, transport_sweep.h): the cells that scatter,
// emit or carry a first-collision amplitude.
SourceRows source_rows(const BandProblem& p);

// Source moments of the sweep from the moments phi, both packed on rows (transport_sweep.h):
// s_k = sigma_s chi*_l(k) phi_k, plus sqrt(4π) q at k = 0 when with_emission. chi: per moment
// k of ang, chi*_l(k) (0 beyond the phase's degree), from moment_chi.
std::vector<double> moment_chi(const BandProblem& p, const AngularSet& ang);
void make_source_moments(const BandProblem& p, const std::vector<double>& chi, const SourceRows& rows,
                         const double* phi, double* s, bool with_emission);

// A problem with optics o (kappa per cell = rho o.sigma_t) and no sources yet (emission 0, nl = 0).
BandProblem make_band_optics(const Medium& m, const BandOptics& o, const Box& own, const AngularSet& ang,
                             bool delta_m);
// The same with the optics of band b.
inline BandProblem make_band_optics(const Medium& m, int b, const Box& own, const AngularSet& ang, bool delta_m) {
    return make_band_optics(m, m.bands[static_cast<size_t>(b)], own, ang, delta_m);
}

// Adds the first-collision sources of the light terms of lt at strengths E0[l] (W/m², one per
// light of lt; optics o as given to make_band_optics). Lights of strength 0 are left out
// (p.nl counts the others), so a problem for the sky alone carries no sun term. Collective;
// returns the cell means of T it used (their bound's scales, for FirstScatterMeans::report).
FirstScatterMeans add_light_sources(BandProblem& p, const Decomposition& d, const Medium& m, const LightTransport& lt,
                                    const BandOptics& o, const std::vector<double>& E0, const AngularSet& ang);
// The same at band b's strengths, E0[l] = the light's E0 in band b.
FirstScatterMeans add_light_sources(BandProblem& p, const Decomposition& d, const Medium& m, const LightTransport& lt,
                                    int b, const AngularSet& ang);

// The light terms of lt without the sky's direction bins ("sky[...]", src/physics/lights.h), for
// DomOptions::sky = "boundary" (the sky then enters as boundary radiance). Copies the fields.
LightTransport without_sky(const LightTransport& lt);

}  // namespace nimbus::dom
