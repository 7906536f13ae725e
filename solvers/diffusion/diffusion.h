// The diffusion (P1) multiple-scattering model on hypre structured multigrid (Max 2004 §2,
// Stam 1995; equation and discretization in diffusion_kernel.h, derivation in README.md).
//
// Parameters (DiffusionOptions, [model.diffusion]):
//   solver          pfmg-pcg   pfmg | smg | pfmg-pcg | smg-pcg | petsc (cross-check path)
//   tolerance       1e-8       TRUE relative residual ||b - A x|| / ||b|| required
//   max_iterations  200        over all restarts of one solve
//   margin          2          cells around the bounding box of the cloud in the solve region
//
// Output per band: fluence = 4π U (W/m²) and flux F (W/m², 3 components), owned box + 1 ghost
// layer (halo-exchanged), zero in empty cells. Bands with equal (sigma_t, albedo, g) share one
// matrix and multigrid setup; among them, bands whose light irradiances E0 are proportional
// share one solve (scaled). Report: values()["diffusion"] and phases "diffusion/...".
#pragma once

#include <memory>

#include "src/model/model.h"
#include "src/model/options.h"

namespace nimbus {

std::unique_ptr<ScatteringModel> make_diffusion_model(const DiffusionOptions& opt);

}  // namespace nimbus
