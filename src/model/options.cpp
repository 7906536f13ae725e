#include "src/model/options.h"

#include <fmt/format.h>

#include "src/core/error.h"

namespace nimbus {

void MonteCarloOptions::validate() const {
    if (photons < 1) throw Error(fmt::format("model.montecarlo.photons = {} must be >= 1", photons));
    if (time_budget < 0) throw Error("model.montecarlo.time_budget must be >= 0 seconds");
    if (target_rel_error < 0 || target_rel_error >= 1)
        throw Error("model.montecarlo.target_rel_error must be in [0, 1)");
    if (batches < 2 || batches > 4096) throw Error("model.montecarlo.batches must be in [2, 4096]");
    if (roulette_weight <= 0 || roulette_weight >= 1)
        throw Error("model.montecarlo.roulette_weight must be in (0, 1)");
    if (max_replicated_memory_gb <= 0) throw Error("model.montecarlo.max_replicated_memory_gb must be > 0");
    if (samples_per_pixel < 1) throw Error("model.montecarlo.samples_per_pixel must be >= 1");
}

void DiffusionOptions::validate() const {
    const bool known = solver == "pfmg" || solver == "smg" || solver == "pfmg-pcg" ||
                       solver == "smg-pcg" || solver == "petsc";
    if (!known)
        throw Error(fmt::format("model.diffusion.solver = '{}': allowed are pfmg, smg, pfmg-pcg, smg-pcg, petsc", solver));
    if (tolerance <= 0 || tolerance >= 1) throw Error("model.diffusion.tolerance must be in (0, 1)");
    if (max_iterations < 1) throw Error("model.diffusion.max_iterations must be >= 1");
    if (margin < 0) throw Error("model.diffusion.margin must be >= 0");
    if (max_transport_length < 0) throw Error("model.diffusion.max_transport_length must be >= 0 (0 = solve region size)");
}

}  // namespace nimbus
