// Builds the DiffusionProblem of one band group from the medium and the light pass
// (DESIGN §1): kappa_tr = rho sigma_t (1 - a g), sigma_a = rho sigma_t (1 - a),
// Q0 = LightTransport::Q0, G = LightTransport::Q1 / kappa_tr, for each right-hand side band.
// Collective over d.comm() (halo exchange of G).
#pragma once

#include "solvers/diffusion/band_groups.h"
#include "solvers/diffusion/diffusion_problem.h"
#include "src/core/decomposition.h"
#include "src/model/model.h"

namespace nimbus::diffusion {

DiffusionProblem make_problem(const Decomposition& d, const Medium& m, const LightTransport& light,
                              const BandGroup& group);

}  // namespace nimbus::diffusion
