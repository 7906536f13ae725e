// Builds the DiffusionProblem of one band group from the medium and the light pass
// (DESIGN §1), with the delta-Eddington optics of delta_scaling.h (plain P1 when
// delta_scaling = false):
//   kappa_tr = rho sigma_t (1 - a g),  sigma_a = rho sigma_t (1 - a)   (invariant under scaling)
//   Q0' = (1/4π) Σ_lights rho sigma_t a (1 - f) E0 T',  T' = exp(-sigma_t (1 - a f) tau_rho)
//   G = Q1'/kappa_tr,  Q1' = g' Σ_lights (1/4π) rho sigma_t a (1 - f) E0 T' w_light
//   + Σ_sources power/4π in the source's covered cells with density (emission.h; isotropic, so
//     it adds to Q0 only and the delta-Eddington split leaves it alone)
// for each right-hand side (weights over the terms: the lights, then `sources`; band_groups.h). G is the first-scatter flux per 4π; it depends on the
// density only through T' (rho cancels), so it is continuous across density jumps.
// The lights' cell means of T' are FirstScatterMeans (src/model/model.h), whose bound it
// reports into report, if given. The first scatter in the sheet under a Marshak face a light
// enters by leaves through that face in part directly (sheet_escape in sources.cpp): that part
// is taken out of Q0 and put in escape_flux. Collective over d.comm() (halo exchange of G).
#pragma once

#include "src/physics/band_groups.h"
#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/decomposition.h"
#include "src/model/model.h"

namespace nimbus::diffusion {

DiffusionProblem make_problem(const Decomposition& d, const Medium& m, const LightTransport& light,
                              const std::vector<VolumeSource>& sources, const BandGroup& group,
                              bool delta_scaling = true, Report* report = nullptr);

// The part of the diffuse fluence that the delta-Eddington scaling keeps in the reduced
// incident field is Σ_lights E0[band] <T' - T> (W/m²), its flux Σ E0 <T' - T> w_light, with the
// cell means of LightTransport::forward_peak_mean (the source integrates the cell's <T'>).
// add_forward_peak adds them to fluence[b] and flux[b] of every band b of the group on the owned
// cells; nothing when the scaling moves nothing (off, or no forward peak). m.rho and
// light.tau_rho with their ghost layers. Not collective.
void add_forward_peak(const Decomposition& d, const Medium& m, const LightTransport& light, const BandGroup& group,
                      bool delta_scaling, std::vector<Field<double>>& fluence, std::vector<Field<double>>& flux);

}  // namespace nimbus::diffusion
