// Options of each multiple-scattering model: plain structs with defaults and validate().
// Only io/ parses text into them ([model.<name>] tables); models take them typed.
//
// Each struct's keys are listed once, in the for_each_option below it: f(key, member) for every
// option, in the order of the scene file. The [model.<name>] table's known keys, its reading
// and writing (io/scene) and the options a model echoes and stores (options_json,
// src/model/model.h) all come from it; tests/unit/io_scene/option_keys_test.cpp checks that
// they agree. A new option: its member here, a line in its for_each_option, a check in
// validate() if it has a range, a non-default value in that test, its meaning in
// io/scene/key_docs.cpp, and docs/scene_reference.toml regenerated
// (tests/unit/io_scene/key_docs_test.cpp says how; it fails for an option without a meaning).
#pragma once

#include <concepts>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

namespace nimbus {

// O is T or const T: one for_each_option serves reading (T&) and writing (const T&).
template <class O, class T>
concept maybe_const = std::same_as<std::remove_const_t<O>, T>;

// Forward light tracing reference (solvers/montecarlo).
struct MonteCarloOptions {
    // At most 10^14: a time budget splits the photons into at most 2^30 batches and traces two of
    // them at least, ~10^5 photons each then (beyond, the budget could not hold: a QA finding).
    static constexpr std::int64_t kMaxPhotons = 100'000'000'000'000;
    std::int64_t photons = 1'000'000;   // photon paths to trace (all lights together)
    double time_budget = 0.0;           // seconds, 0 = no limit
    double target_rel_error = 0.0;      // stop when the relative standard error of the total
                                        // diffuse fluence falls below this (0 = off)
    std::uint64_t seed = 1;             // counter-based RNG key: same seed, same result, any rank count
    int batches = 32;                   // batch means for the per-cell standard error, 2..kMaxBatches
    static constexpr int kMaxBatches = 4096;
    double roulette_weight = 0.05;      // Russian roulette below this weight (survival 0.5)
    double max_replicated_memory_gb = 8.0;  // the density grid is replicated on every rank
    bool image = false;                 // also path-trace the camera image
    int samples_per_pixel = 64;         // for the path-traced image
    std::string kernel = "auto";        // forward paths: auto (lanes where the CPU has AVX-512) | lanes | scalar
    bool flux = false;                  // tally the diffuse flux F (flux_diffuse; the ray caster's in-scatter
                                        // then uses it): 10-12% of the tracing; noisy at 1e6 photons
    bool empty_cells = false;           // tally fluence_diffuse in the empty cells too (DESIGN defines it
                                        // there; off, they stay 0 and the walk jumps across empty space):
                                        // about 2x the tracing time on the default cloud
    void validate() const;
    bool operator==(const MonteCarloOptions&) const = default;
};

// [model.montecarlo]
template <maybe_const<MonteCarloOptions> O, class F>
void for_each_option(O& o, F&& f) {
    f("photons", o.photons);
    f("time_budget", o.time_budget);
    f("target_rel_error", o.target_rel_error);
    f("seed", o.seed);
    f("batches", o.batches);
    f("roulette_weight", o.roulette_weight);
    f("max_replicated_memory_gb", o.max_replicated_memory_gb);
    f("image", o.image);
    f("samples_per_pixel", o.samples_per_pixel);
    f("kernel", o.kernel);
    f("flux", o.flux);
    f("empty_cells", o.empty_cells);
}

// The diffusion model on hypre (solvers/diffusion).
struct DiffusionOptions {
    std::string solver = "pfmg-pcg";  // pfmg | smg | pfmg-pcg | smg-pcg | petsc
    double tolerance = 1e-8;          // relative residual
    int max_iterations = 200;
    int margin = 2;                   // cells of margin around the bounding box of non-empty cells
    double max_transport_length = 0;  // m, cap on 1/kappa_tr in D and G (0 = half the smallest non-periodic
                                      // extent of each piece of cloud's bounding box, transport_floor)
    bool clamp_negative = true;       // set negative P1 fluence (boundary layers lit by a strongly
                                      // forward-scattered source) to 0; counts are reported
    bool delta_scaling = true;        // delta-Eddington optics for the P1 solve (solvers/diffusion)
    std::string flux_limiter = "none";  // none | levermore-pomraning (flux-limited diffusion)
    int limiter_iterations = 50;      // iterations of the flux limiter at most
    double limiter_tolerance = 1e-2;  // stop when max |ΔU| / max U falls below this
    // solver = petsc: PETSc options for its KSP/PC/DM (prefix "diffusion_"), e.g.
    // "-diffusion_pc_type mg -diffusion_pc_mg_levels 3 -diffusion_pc_mg_galerkin both".
    // Empty: CG + BoomerAMG, and PETSc's global options (PETSC_OPTIONS) apply.
    std::string petsc_options;
    // Every check: the ranges, and no setting that the other settings leave unread (limiter keys
    // without the limiter, petsc_options without solver = petsc). For the model in use.
    void validate() const;
    // The ranges only: a scene whose model is another one keeps its [model.diffusion] table
    // unread, so a setting there that diffusion would not read is no error.
    void validate_ranges() const;
    bool operator==(const DiffusionOptions&) const = default;
};

// [model.diffusion]
template <maybe_const<DiffusionOptions> O, class F>
void for_each_option(O& o, F&& f) {
    f("solver", o.solver);
    f("tolerance", o.tolerance);
    f("max_iterations", o.max_iterations);
    f("margin", o.margin);
    f("max_transport_length", o.max_transport_length);
    f("clamp_negative", o.clamp_negative);
    f("delta_scaling", o.delta_scaling);
    f("flux_limiter", o.flux_limiter);
    f("limiter_iterations", o.limiter_iterations);
    f("limiter_tolerance", o.limiter_tolerance);
    f("petsc_options", o.petsc_options);
}

// Discrete ordinates (solvers/dom).
struct DomOptions {
    std::string quadrature = "level-symmetric";  // level-symmetric | product | cube96
    int order = 4;                  // S_N order for level-symmetric (even, 2..16); 4: see solvers/dom/README.md
    int polar = 8;                  // product set: Gauss-Legendre polar points (over [-1, 1])
    int azimuthal = 16;             // product set: Chebyshev azimuths
    int legendre_order = 3;         // L: HG expanded in Legendre moments 0..L (delta-M f = chi_{L+1})
    bool delta_m = true;            // delta-M scaling of the truncated phase function (Wiscombe 1977)
    std::string scheme = "step";    // step | diamond (with negative-flux fix-up)
    std::string iteration = "dsa";  // source | dsa | gmres (DSA-preconditioned) | gmres-plain
    double tolerance = 1e-4;        // relative change / residual of the scalar flux
    int max_iterations = 500;
    int tile_rows = 8;              // KBA block rows across the slab face
    int octant_overlap = 8;         // octants swept at once: 1, 2 (+z/-z pairs) or 8 (solvers/dom/transport_sweep.h)
    std::vector<std::string> reflective;  // specular domain faces: any of x-, x+, y-, y+, z-, z+
    std::string sky = "first-collision";  // first-collision | boundary (sky radiance enters at the faces)
    void validate() const;
    bool operator==(const DomOptions&) const = default;
};

// [model.dom]
template <maybe_const<DomOptions> O, class F>
void for_each_option(O& o, F&& f) {
    f("quadrature", o.quadrature);
    f("order", o.order);
    f("polar", o.polar);
    f("azimuthal", o.azimuthal);
    f("legendre_order", o.legendre_order);
    f("delta_m", o.delta_m);
    f("scheme", o.scheme);
    f("iteration", o.iteration);
    f("tolerance", o.tolerance);
    f("max_iterations", o.max_iterations);
    f("tile_rows", o.tile_rows);
    f("octant_overlap", o.octant_overlap);
    f("reflective", o.reflective);
    f("sky", o.sky);
}

// Light propagation maps (solvers/lpm, Fattal 2009).
struct LpmOptions {
    int p = 6;                  // directions per map: p x p (even: no horizontal rays, solvers/lpm/lpm.h)
    int refinement = 1;         // map rays per grid cell along each map axis
    int k = 1;                  // coarse angular bins of the unpropagated field U: 6 k^2 (p % k == 0)
    int solution_bins = 1;      // solution moments: 1 = fluence only, 4 = fluence + flux F
    int iterations = 3;         // map sweeps (all six maps) at most
    double epsilon = 1e-3;      // stop when max U < epsilon x max first-scatter source
    std::string tail = "dsa";  // light left in U at the stop: none | geometric | diffusion (solvers/lpm/
                               // tail.h) | dsa (diffusion fed back every round, solve_band.h)
    void validate() const;
    bool operator==(const LpmOptions&) const = default;
};

// [model.lpm]
template <maybe_const<LpmOptions> O, class F>
void for_each_option(O& o, F&& f) {
    f("p", o.p);
    f("refinement", o.refinement);
    f("k", o.k);
    f("solution_bins", o.solution_bins);
    f("iterations", o.iterations);
    f("epsilon", o.epsilon);
    f("tail", o.tail);
}

// Path-integral point-spread function (solvers/psf, Premoze 2004).
struct PsfOptions {
    int levels = 0;              // pyramid levels (0 = as many as the grid allows)
    double step_growth = 1.0;    // view-ray sample spacing grows with the blur width by this factor
    void validate() const;
    bool operator==(const PsfOptions&) const = default;
};

// [model.psf]
template <maybe_const<PsfOptions> O, class F>
void for_each_option(O& o, F&& f) {
    f("levels", o.levels);
    f("step_growth", o.step_growth);
}

// The keys for_each_option visits, in order: the known keys of the [model.<name>] table.
template <class Options>
std::vector<std::string> option_keys(const Options& o) {
    std::vector<std::string> keys;
    for_each_option(o, [&](const char* key, const auto&) { keys.emplace_back(key); });
    return keys;
}

}  // namespace nimbus
