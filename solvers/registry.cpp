#include "solvers/registry.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "solvers/single/single.h"
#include "src/core/error.h"
#if NIMBUS_HAVE_MODEL_MONTECARLO
#include "solvers/montecarlo/montecarlo.h"
#endif
#if NIMBUS_HAVE_MODEL_DIFFUSION
#include "solvers/diffusion/diffusion.h"
#endif

namespace nimbus {

std::vector<std::string> available_models() {
    std::vector<std::string> names{"single"};
#if NIMBUS_HAVE_MODEL_MONTECARLO
    names.push_back("montecarlo");
#endif
#if NIMBUS_HAVE_MODEL_DIFFUSION
    names.push_back("diffusion");
#endif
    return names;
}

std::unique_ptr<ScatteringModel> make_model(const ModelSpec& spec) {
    if (spec.name == "single") return make_single_model();
#if NIMBUS_HAVE_MODEL_MONTECARLO
    if (spec.name == "montecarlo") {
        spec.montecarlo.validate();
        return make_montecarlo_model(spec.montecarlo);
    }
#endif
#if NIMBUS_HAVE_MODEL_DIFFUSION
    if (spec.name == "diffusion") {
        spec.diffusion.validate();
        return make_diffusion_model(spec.diffusion);
    }
#endif
    throw Error(fmt::format("model.name = '{}' is not available in this build; available: {}",
                            spec.name, fmt::join(available_models(), ", ")));
}

}  // namespace nimbus
