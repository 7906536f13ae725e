#include "src/model/options.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "src/core/error.h"

namespace nimbus {

void MonteCarloOptions::validate() const {
    if (photons < 1 || photons > kMaxPhotons)
        throw Error(fmt::format("model.montecarlo.photons = {} must be in [1, {:.0e}] (10^14 paths take months at "
                                "10^7 collisions/s; time_budget or target_rel_error stop a run earlier)",
                                photons, static_cast<double>(kMaxPhotons)));
    if (!(time_budget >= 0 && std::isfinite(time_budget))) throw Error("model.montecarlo.time_budget must be >= 0 seconds");
    if (!(target_rel_error >= 0 && target_rel_error < 1))
        throw Error("model.montecarlo.target_rel_error must be in [0, 1)");
    if (batches < 2 || batches > kMaxBatches)
        throw Error(fmt::format("model.montecarlo.batches must be in [2, {}]", kMaxBatches));
    if (!(roulette_weight > 0 && roulette_weight < 1))
        throw Error("model.montecarlo.roulette_weight must be in (0, 1)");
    if (!(max_replicated_memory_gb > 0 && std::isfinite(max_replicated_memory_gb))) throw Error("model.montecarlo.max_replicated_memory_gb must be > 0");
    if (samples_per_pixel < 1) throw Error("model.montecarlo.samples_per_pixel must be >= 1");
    if (kernel != "auto" && kernel != "lanes" && kernel != "scalar")
        throw Error(fmt::format("model.montecarlo.kernel = '{}': allowed are auto, lanes, scalar", kernel));
}

void DiffusionOptions::validate_ranges() const {
    const bool known = solver == "pfmg" || solver == "smg" || solver == "pfmg-pcg" ||
                       solver == "smg-pcg" || solver == "petsc";
    if (!known)
        throw Error(fmt::format("model.diffusion.solver = '{}': allowed are pfmg, smg, pfmg-pcg, smg-pcg, petsc", solver));
    if (!(tolerance > 0 && tolerance < 1)) throw Error("model.diffusion.tolerance must be in (0, 1)");
    if (max_iterations < 1) throw Error("model.diffusion.max_iterations must be >= 1");
    if (margin < 0) throw Error("model.diffusion.margin must be >= 0");
    if (!(max_transport_length >= 0 && std::isfinite(max_transport_length))) throw Error("model.diffusion.max_transport_length must be >= 0 (0 = half the smallest non-periodic extent of each piece of cloud's bounding box)");
    if (flux_limiter != "none" && flux_limiter != "levermore-pomraning")
        throw Error(fmt::format("model.diffusion.flux_limiter = '{}': allowed are none, levermore-pomraning", flux_limiter));
    if (limiter_iterations < 1) throw Error("model.diffusion.limiter_iterations must be >= 1");
    if (!(limiter_tolerance > 0 && limiter_tolerance < 1)) throw Error("model.diffusion.limiter_tolerance must be in (0, 1)");
}

void DiffusionOptions::validate() const {
    validate_ranges();
    // Like petsc_options: a limiter setting without the limiter would be ignored silently.
    // (A value other than the default is what is seen: the default itself passes.)
    const DiffusionOptions defaults;
    if (flux_limiter == "none" && limiter_iterations != defaults.limiter_iterations)
        throw Error(fmt::format("model.diffusion.limiter_iterations = {} is read only with flux_limiter = "
                                "\"levermore-pomraning\"",
                                limiter_iterations));
    if (flux_limiter == "none" && limiter_tolerance != defaults.limiter_tolerance)
        throw Error(fmt::format("model.diffusion.limiter_tolerance = {:g} is read only with flux_limiter = "
                                "\"levermore-pomraning\"",
                                limiter_tolerance));
    if (!petsc_options.empty() && solver != "petsc")
        throw Error("model.diffusion.petsc_options is read only with solver = \"petsc\"");
}

void DomOptions::validate() const {
    if (quadrature != "level-symmetric" && quadrature != "product" && quadrature != "cube96")
        throw Error(fmt::format("model.dom.quadrature = '{}': allowed are level-symmetric, product, cube96", quadrature));
    if (order < 2 || order > 16 || order % 2 != 0) throw Error("model.dom.order must be even, 2..16");
    if (polar < 2 || polar % 2 != 0) throw Error("model.dom.polar must be even and >= 2");
    if (azimuthal < 1) throw Error("model.dom.azimuthal must be >= 1");
    // The product set puts no direction in a coordinate plane only with whole quadrants of
    // azimuths (src/physics/quadrature.h); checked here so that the error names the key.
    if (quadrature == "product" && azimuthal % 4 != 0)
        throw Error(fmt::format("model.dom.azimuthal = {} must be a multiple of 4 with quadrature = \"product\" "
                                "(no direction in a coordinate plane)",
                                azimuthal));
    // S16, the largest order, integrates the moments to 15 (beyond it a run warns of aliasing);
    // 1000 was refused as "the grid does not fit in memory" (its (L+1)² moments per cell)
    // without naming the key (a QA finding).
    if (legendre_order < 0 || legendre_order > 64)
        throw Error(fmt::format("model.dom.legendre_order = {} must be in [0, 64] (S{} integrates moments to {})",
                                legendre_order, order, order - 1));
    if (scheme != "step" && scheme != "diamond")
        throw Error(fmt::format("model.dom.scheme = '{}': allowed are step, diamond", scheme));
    if (iteration != "source" && iteration != "dsa" && iteration != "gmres" && iteration != "gmres-plain")
        throw Error(fmt::format("model.dom.iteration = '{}': allowed are source, dsa, gmres, gmres-plain", iteration));
    if (!(tolerance > 0 && tolerance < 1)) throw Error("model.dom.tolerance must be in (0, 1)");
    if (max_iterations < 1) throw Error("model.dom.max_iterations must be >= 1");
    if (tile_rows < 1) throw Error("model.dom.tile_rows must be >= 1");
    if (octant_overlap != 1 && octant_overlap != 2 && octant_overlap != 8)
        throw Error(fmt::format("model.dom.octant_overlap = {}: allowed are 1, 2, 8", octant_overlap));
    const std::vector<std::string> faces = {"x-", "x+", "y-", "y+", "z-", "z+"};
    for (size_t i = 0; i < reflective.size(); ++i) {
        if (std::find(faces.begin(), faces.end(), reflective[i]) == faces.end())
            throw Error(fmt::format("model.dom.reflective: '{}' is not a face (allowed: x-, x+, y-, y+, z-, z+)", reflective[i]));
        if (std::find(reflective.begin(), reflective.begin() + static_cast<std::ptrdiff_t>(i), reflective[i]) !=
            reflective.begin() + static_cast<std::ptrdiff_t>(i))
            throw Error(fmt::format("model.dom.reflective: face '{}' is listed twice", reflective[i]));
        // A high face reflects the previous sweep's outgoing light (solvers/dom/transport_sweep.h):
        // fine inside source/DSA iteration, but not a fixed linear operator for GMRES.
        if (reflective[i].back() == '+' && iteration.rfind("gmres", 0) == 0)
            throw Error(fmt::format("model.dom.reflective = '{}' (a high face) needs iteration = source or dsa, not {}",
                                    reflective[i], iteration));
    }
    if (sky != "first-collision" && sky != "boundary")
        throw Error(fmt::format("model.dom.sky = '{}': allowed are first-collision, boundary", sky));
}

void LpmOptions::validate() const {
    if (p < 1) throw Error("model.lpm.p must be >= 1 (p x p directions per map)");
    if (refinement < 1) throw Error("model.lpm.refinement must be >= 1");
    if (k < 1) throw Error("model.lpm.k must be >= 1");
    if (p % k != 0) throw Error("model.lpm.k must divide model.lpm.p (each map bin inside one coarse bin, Fattal 2009 §3.3)");
    if (solution_bins != 1 && solution_bins != 4)
        throw Error("model.lpm.solution_bins must be 1 (fluence) or 4 (fluence and flux)");
    if (iterations < 1) throw Error("model.lpm.iterations must be >= 1");
    if (!(epsilon >= 0 && epsilon < 1)) throw Error("model.lpm.epsilon must be in [0, 1)");
    if (tail != "none" && tail != "geometric" && tail != "diffusion" && tail != "dsa")
        throw Error("model.lpm.tail must be none, geometric, diffusion or dsa");
}

void PsfOptions::validate() const {
    if (levels < 0) throw Error("model.psf.levels must be >= 0 (0 = automatic)");
    if (!(step_growth >= 0 && std::isfinite(step_growth))) throw Error("model.psf.step_growth must be >= 0");
}

}  // namespace nimbus
