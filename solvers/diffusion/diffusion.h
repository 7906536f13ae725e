// The diffusion (P1) multiple-scattering model on hypre structured multigrid (Max 2004 §2,
// Stam 1995; equation and discretization in diffusion_kernel.h, derivation in README.md).
//
// Parameters (DiffusionOptions, [model.diffusion]):
//   solver          pfmg-pcg   pfmg | smg | pfmg-pcg | smg-pcg | petsc (cross-check path)
//   tolerance       1e-8       TRUE relative residual ||b - A x|| / ||b|| required
//   max_iterations  200        over all restarts of one solve
//   margin          2          cells around the bounding box of the cloud in the solve region
//                              (cost only: the answer does not depend on it)
//
// Output per band: fluence = 4π U' + E0 (T' - T) (W/m²) and flux F (W/m², 3 components), owned
// box + 1 ghost layer (halo-exchanged). U' is the P1 solution, zero in empty cells; the second
// term is the delta-Eddington forward peak (delta_scaling.h), once-scattered light kept in the
// collimated beam, which is non-zero wherever the beam has been scattered, also in empty cells
// in a cloud's shadow (and the peak's flux E0 (T' - T) w_light likewise). Bands with equal (sigma_t, albedo, g) share one
// matrix and multigrid setup; among them, bands whose light irradiances E0 are proportional
// share one solve (scaled). Report: values()["diffusion"] and phases "diffusion/...".
#pragma once

#include <memory>

#include "src/model/model.h"
#include "src/model/options.h"

namespace nimbus {

std::unique_ptr<ScatteringModel> make_diffusion_model(const DiffusionOptions& opt);

}  // namespace nimbus
