// Each model's option keys are listed once, in for_each_option (src/model/options.h); the scene
// reader's known keys and reads, the scene writer's [model.<name>] sections and the options a
// model echoes and stores (ScatteringModel::options()) must all follow that list. For every
// options struct, with a value for every key that differs from its default (so a key added to
// for_each_option fails here until it gets one below):
//   - the writer writes exactly the visited keys, in order, and its text reads back equal;
//   - an unknown key's error lists exactly the visited keys;
//   - the model's options() JSON has exactly the visited keys, with the set values.
#include <gtest/gtest.h>

#include <algorithm>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "io/scene/scene_toml.h"
#include "solvers/registry.h"
#include "src/core/error.h"
#include "src/model/model.h"

namespace nimbus {

// gtest prints options as their JSON.
void PrintTo(const MonteCarloOptions& o, std::ostream* os) { *os << options_json(o).dump(); }
void PrintTo(const DiffusionOptions& o, std::ostream* os) { *os << options_json(o).dump(); }
void PrintTo(const DomOptions& o, std::ostream* os) { *os << options_json(o).dump(); }
void PrintTo(const LpmOptions& o, std::ostream* os) { *os << options_json(o).dump(); }
void PrintTo(const PsfOptions& o, std::ostream* os) { *os << options_json(o).dump(); }

namespace {

// Values other than the defaults for every key, valid together (validate() passes).
MonteCarloOptions custom_montecarlo() {
    return {.photons = 123456789012, .time_budget = 60.0, .target_rel_error = 0.01,
            .seed = 9876543210, .batches = 16, .roulette_weight = 0.1,
            .max_replicated_memory_gb = 2.5, .image = true, .samples_per_pixel = 8,
            .kernel = "scalar", .flux = true, .empty_cells = true};
}
DiffusionOptions custom_diffusion() {
    return {.solver = "petsc", .tolerance = 1e-10, .max_iterations = 999, .margin = 5,
            .max_transport_length = 123.5, .clamp_negative = false, .delta_scaling = false,
            .flux_limiter = "levermore-pomraning", .limiter_iterations = 7,
            .limiter_tolerance = 0.125,
            .petsc_options = "-diffusion_pc_type mg -diffusion_pc_mg_levels 2"};
}
DomOptions custom_dom() {
    return {.quadrature = "product", .order = 8, .polar = 4, .azimuthal = 8, .legendre_order = 5,
            .delta_m = false, .scheme = "diamond", .iteration = "source", .tolerance = 1e-5,
            .max_iterations = 99, .tile_rows = 4, .octant_overlap = 2, .reflective = {"z-", "x+"},
            .sky = "boundary"};
}
LpmOptions custom_lpm() {
    return {.p = 4, .refinement = 2, .k = 2, .solution_bins = 4, .iterations = 5, .epsilon = 0.01,
            .tail = "none"};
}
PsfOptions custom_psf() { return {.levels = 3, .step_growth = 0.5}; }

// The "key = value" lines of section [model.<name>] of a written scene, keys only.
std::vector<std::string> written_keys(const std::string& toml, const std::string& name) {
    std::istringstream in(toml.substr(toml.find("[model." + name + "]\n")));
    std::string line;
    std::getline(in, line);  // the header
    std::vector<std::string> keys;
    while (std::getline(in, line) && !line.empty() && line.front() != '[')
        keys.push_back(line.substr(0, line.find(" = ")));
    return keys;
}

template <class Options>
void check_options(const std::string& name, Options ModelSpec::*member, const Options& custom) {
    SCOPED_TRACE("model." + name);
    const std::vector<std::string> keys = option_keys(custom);
    ASSERT_FALSE(keys.empty());

    // The test's values differ from the defaults in every key, so every check below sees each key.
    const nlohmann::json defaults = options_json(Options{}), set = options_json(custom);
    ASSERT_EQ(defaults.size(), keys.size()) << "a key is visited twice";
    for (const std::string& k : keys)
        EXPECT_NE(set.at(k), defaults.at(k)) << "give model." << name << "." << k
                                             << " a value other than its default in custom_"
                                             << name << "()";
    ASSERT_NO_THROW(custom.validate());

    // Writer -> reader: every visited key is written, in order, and read back.
    Scene s = default_scene();
    s.model.*member = custom;
    const std::string text = scene_to_toml(s);
    EXPECT_EQ(written_keys(text, name), keys);
    Scene back;
    ASSERT_NO_THROW(back = load_scene_string(text, "<round trip>"));
    EXPECT_EQ(back.model.*member, custom);

    // The reader's known keys are the visited keys.
    try {
        default_scene({"model." + name + ".no_such_key=1"});
        ADD_FAILURE() << "no error for an unknown key";
    } catch (const Error& e) {
        std::string allowed;
        for (const std::string& k : keys) allowed += (allowed.empty() ? "" : ", ") + k;
        const std::string msg = e.what();
        EXPECT_NE(msg.find("model." + name + ".no_such_key: unknown key"), std::string::npos)
            << msg;
        EXPECT_EQ(msg.substr(msg.find("allowed: ")), "allowed: " + allowed);
    }

    // The model echoes (and stores) exactly the visited keys, with their values.
    // A model left out of a NIMBUS_MODELS subset build has nothing to echo: make_model must
    // then refuse it by name (the checks above ran either way).
    ModelSpec spec;
    spec.name = name;
    spec.*member = custom;
    const std::vector<std::string> built = available_models();
    if (std::find(built.begin(), built.end(), name) == built.end()) {
        try {
            make_model(spec);
            ADD_FAILURE() << "make_model accepted '" << name << "', which is not in available_models()";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("'" + name + "' is not available in this build"), std::string::npos)
                << e.what();
        }
        return;
    }
    const nlohmann::json echoed = make_model(spec)->options();
    std::vector<std::string> echoed_keys;
    for (const auto& [k, v] : echoed.items()) echoed_keys.push_back(k);
    std::vector<std::string> sorted = keys;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(echoed_keys, sorted);  // nlohmann::json orders an object's keys
    EXPECT_EQ(echoed, set);
}

TEST(OptionKeys, MonteCarlo) {
    check_options("montecarlo", &ModelSpec::montecarlo, custom_montecarlo());
}
TEST(OptionKeys, Diffusion) {
    check_options("diffusion", &ModelSpec::diffusion, custom_diffusion());
}
TEST(OptionKeys, Dom) { check_options("dom", &ModelSpec::dom, custom_dom()); }
TEST(OptionKeys, Lpm) { check_options("lpm", &ModelSpec::lpm, custom_lpm()); }
TEST(OptionKeys, Psf) { check_options("psf", &ModelSpec::psf, custom_psf()); }

}  // namespace
}  // namespace nimbus
