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
#if NIMBUS_HAVE_MODEL_DOM
#include "solvers/dom/dom.h"
#endif
#if NIMBUS_HAVE_MODEL_LPM
#include "solvers/lpm/lpm.h"
#endif
#if NIMBUS_HAVE_MODEL_PSF
#include "solvers/psf/psf.h"
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
#if NIMBUS_HAVE_MODEL_DOM
    names.push_back("dom");
#endif
#if NIMBUS_HAVE_MODEL_LPM
    names.push_back("lpm");
#endif
#if NIMBUS_HAVE_MODEL_PSF
    names.push_back("psf");
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
#if NIMBUS_HAVE_MODEL_DOM
    if (spec.name == "dom") {
        spec.dom.validate();
        return make_dom_model(spec.dom);
    }
#endif
#if NIMBUS_HAVE_MODEL_LPM
    if (spec.name == "lpm") {
        spec.lpm.validate();
        return make_lpm_model(spec.lpm);
    }
#endif
#if NIMBUS_HAVE_MODEL_PSF
    if (spec.name == "psf") {
        spec.psf.validate();
        return make_psf_model(spec.psf);
    }
#endif
    throw Error(fmt::format("model.name = '{}' is not available in this build; available: {}",
                            spec.name, fmt::join(available_models(), ", ")));
}

}  // namespace nimbus
