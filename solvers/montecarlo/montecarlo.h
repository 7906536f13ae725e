// The Monte Carlo reference model (issue 3): forward light tracing for fluence_diffuse with
// per-cell standard errors and flux_diffuse (track length, no standard error; forward.h), and
// optionally a path-traced camera image
// (path_tracer.h). Parameters ([model.montecarlo], MonteCarloOptions in src/model/options.h):
//
//   | name                     | default | meaning                                          |
//   | photons                  | 1e6     | photon paths over all light terms                |
//   | time_budget              | 0 (off) | seconds; kept to within a chunk (forward.h)      |
//   | target_rel_error         | 0 (off) | stop when the total diffuse power is this exact  |
//   | seed                     | 1       | same seed, same result on any rank count         |
//   | batches                  | 32      | batch means for the standard errors              |
//   | roulette_weight          | 0.05    | Russian roulette below this weight               |
//   | max_replicated_memory_gb | 8       | the density grid is replicated on every rank     |
//   | image, samples_per_pixel | false,64| path-trace the camera image                      |
#pragma once

#include <memory>

#include "src/model/model.h"
#include "src/model/options.h"

namespace nimbus {

// Validates opt (throws Error). The model is collective in solve() and render().
std::unique_ptr<ScatteringModel> make_montecarlo_model(const MonteCarloOptions& opt);

}  // namespace nimbus
