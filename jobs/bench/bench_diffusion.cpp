// Benchmark of the diffusion model (solvers/diffusion) on the built-in cumulus at N³.
//
//   mpiexec -n 2 ./bench_diffusion 128          (jobs/bench_diffusion.sh runs the sweep)
//
// For each hypre solver (pfmg-pcg, smg-pcg, pfmg, smg) the whole diffusion phase of the model
// (sources, region, assembly, setup, solve, true residual, flux, halo) is timed, next to a
// bare hypre PFMG-PCG solve of the same matrix and right-hand side with the model's PFMG
// settings (setup + solve only, no residual check): the floor the model is measured against. Domain 1.28 km, sigma_t 0.05/m,
// a = 0.9, g = 0.85, sun along (0.3, 0.2, -1); tolerance 1e-8 (true relative residual).
// A warm-up solve runs first (the first hypre setup pays for paging memory in). BENCH_REPS
// (default 1) repeats the sequence bare, then every solver, and prints medians: a run's setup
// depends on what the run before it left in the heap (at 192³ the first model setup after the
// bare solve took 0.145 s, the next ones 0.06 s, as the bare one), so single runs are noisy.
// Prints a markdown table on rank 0; times are the max over ranks.
#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "jobs/bench/bench_support.h"
#include "solvers/diffusion/assemble.h"
#include "src/physics/band_groups.h"
#include "solvers/diffusion/diffusion.h"
#include "solvers/diffusion/hypre_struct.h"
#include "solvers/diffusion/solve_region.h"
#include "solvers/diffusion/sources.h"
#include "solvers/light/sun_transmittance.h"
#include "src/core/error.h"
#include "src/core/log.h"
#include "src/core/mpi_init.h"
#include "src/scene/medium.h"

namespace {

using namespace nimbus;
using bench::max_over_ranks;
using bench::median;

struct Bare {
    int iterations = 0;
    double setup = 0, solve = 0;
};

// hypre PFMG-PCG on the model's matrix, nothing else: the floor.
Bare bare_pfmg_pcg(const Decomposition& d, const diffusion::DiffusionProblem& p) {
    const auto region = diffusion::find_solve_region(d, p, DiffusionOptions{}.margin);
    const diffusion::TransportFloor floor = diffusion::transport_floor(d, p, region, 0.0);
    const diffusion::Assembler as(p, floor);  // as the model
    const Box box = d.local().intersect(region.box);
    diffusion::hypre::Grid grid(d.comm(), box, {0, 0, 0});
    diffusion::hypre::SymmetricStencil7 stencil;
    diffusion::hypre::Matrix A(d.comm(), grid, stencil);
    std::vector<double> vals, rhs;
    for_each_cell(box, [&](int i, int j, int k) {
        const auto row = as.row(i, j, k);
        vals.insert(vals.end(), {row.diag, -row.coupling[diffusion::kXm],
                                 -row.coupling[diffusion::kYm], -row.coupling[diffusion::kZm]});
        rhs.push_back(as.rhs(0, i, j, k));
    });
    A.set_box_values(box, vals);
    A.assemble();
    diffusion::hypre::Vector b(d.comm(), grid), x(d.comm(), grid);
    b.set_box_values(box, rhs);
    b.assemble();
    x.assemble();
    // The model's own solver object (hypre_struct.h): PCG with the same PFMG V-cycle
    // (red/black GS, 2/2 sweeps on every level), so that the ratio measures what the model
    // adds (sources, region, assembly, true-residual check, flux), not a different smoother.
    diffusion::hypre::Solver solver(d.comm(), "pfmg-pcg", false);
    solver.set_tolerance(1e-8);
    solver.set_max_iterations(200);
    Bare out;
    MPI_Barrier(d.comm());
    double t0 = MPI_Wtime();
    solver.setup(A, b, x);
    out.setup = max_over_ranks(MPI_Wtime() - t0, d.comm());
    MPI_Barrier(d.comm());
    t0 = MPI_Wtime();
    solver.solve(A, b, x);
    out.solve = max_over_ranks(MPI_Wtime() - t0, d.comm());
    out.iterations = solver.iterations();
    return out;
}

}  // namespace

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    nimbus::log::init(rank, "warn");
    const int N = argc > 1 ? std::atoi(argv[1]) : 64;
    std::vector<std::string> solvers = {"pfmg-pcg", "smg-pcg", "pfmg", "smg"};
    if (argc > 2) solvers.assign(argv + 2, argv + argc);
    // BENCH_MEDIUM=smooth: the same cumulus without edge noise (noise_amplitude 0), to separate
    // the effect of the rough cloud edge on the iteration count from that of N.
    const char* medium_env = std::getenv("BENCH_MEDIUM");
    const std::string medium = medium_env ? medium_env : "cumulus";
    std::string label = medium;  // the tables' name of the medium
    int status = 0;
    try {
        Decomposition d(MPI_COMM_WORLD, {N, N, N});
        Medium m;
        m.grid.n = {N, N, N};
        m.grid.h = 1280.0 / N;
        m.rho = Field<double>(d.local(), 1, 1, 0.0);
        MediumSpec spec;
        if (medium == "smooth") spec.noise_amplitude = 0.0;
        else if (medium != "cumulus") throw Error("BENCH_MEDIUM must be cumulus or smooth");
        // BENCH_OCTAVES, BENCH_NOISE_SCALE: the edge noise's octaves (default 4) and feature size
        // (grid fractions, default 0.12), to see how the cloud's roughness drives the iterations.
        auto env_number = [](const char* name, double lo, double hi, bool integer, double fallback) {
            const char* v = std::getenv(name);
            if (!v) return fallback;
            char* end = nullptr;
            const double x = std::strtod(v, &end);
            if (end == v || *end != '\0' || !(x >= lo && x <= hi) || (integer && x != static_cast<int>(x)))
                throw Error(fmt::format("{} must be {} in [{}, {}], not '{}'", name, integer ? "an integer" : "a number",
                                        lo, hi, v));
            return x;
        };
        spec.noise_octaves = static_cast<int>(env_number("BENCH_OCTAVES", 1, 8, true, spec.noise_octaves));
        spec.noise_scale = env_number("BENCH_NOISE_SCALE", 0.01, 1.0, false, spec.noise_scale);
        const MediumSpec defaults;
        if (medium != "smooth" && (spec.noise_octaves != defaults.noise_octaves || spec.noise_scale != defaults.noise_scale))
            label = fmt::format("{} (noise: {} octaves, scale {:g})", medium, spec.noise_octaves, spec.noise_scale);
        fill_procedural_density(spec, d, m.rho);
        m.bands = {BandOptics{"gray", 0.05, 0.9, 0.85}};
        const std::vector<DirectionalLight> lights = {
            DirectionalLight{"sun", normalized(Vec3{0.3, 0.2, -1.0}), {1.0}}};
        Report light_report;
        const LightTransport light = compute_light_transport(d, m, lights, light_report);
        Scene scene;

        auto run = [&](const std::string& solver, Report& report) {
            DiffusionOptions opt;
            opt.solver = solver;
            opt.max_iterations = 1000;
            auto model = make_diffusion_model(opt);
            DiffuseSolution sol;
            MPI_Barrier(d.comm());
            model->solve(SolveContext{scene, d, m, light, report}, sol);
        };
        {
            Report warm;
            run("pfmg-pcg", warm);
        }
        const auto groups = group_bands(m.bands, term_strengths(lights, {}, m.nbands()));
        const auto problem = diffusion::make_problem(d, m, light, {}, groups[0]);
        const char* reps_env = std::getenv("BENCH_REPS");
        const int reps = std::max(1, reps_env ? std::atoi(reps_env) : 1);
        // Per repetition: the bare solve, then each solver's phase (times: max over ranks).
        struct Times {
            std::vector<double> assemble, setup, solve, total, sources, region_time, flux, bands;
            int iterations = 0, region = 0;
            double residual = 0.0;
            std::string failure;
        };
        std::vector<double> bare_setup, bare_solve;
        int bare_iterations = 0;
        std::vector<Times> times(solvers.size());
        for (int r = 0; r < reps; ++r) {
            const Bare bare = bare_pfmg_pcg(d, problem);
            bare_setup.push_back(bare.setup);
            bare_solve.push_back(bare.solve);
            bare_iterations = bare.iterations;
            for (size_t q = 0; q < solvers.size(); ++q) {
                Report report;
                Times& t = times[q];
                try {
                    run(solvers[q], report);
                } catch (const Error& e) {
                    t.failure = e.what();
                }
                t.total.push_back(max_over_ranks(report.time("diffusion"), d.comm()));
                t.assemble.push_back(max_over_ranks(report.time("diffusion/assemble"), d.comm()));
                t.setup.push_back(max_over_ranks(report.time("diffusion/setup"), d.comm()));
                t.solve.push_back(max_over_ranks(report.time("diffusion/solve"), d.comm()));
                t.sources.push_back(max_over_ranks(report.time("diffusion/sources"), d.comm()));
                t.region_time.push_back(max_over_ranks(report.time("diffusion/region"), d.comm()));
                t.flux.push_back(max_over_ranks(report.time("diffusion/flux"), d.comm()));
                t.bands.push_back(max_over_ranks(report.time("diffusion/bands"), d.comm()));
                if (t.failure.empty()) {
                    const auto& v = report.values()["diffusion"];
                    t.iterations = v["systems"][0]["iterations"].get<int>();
                    t.residual = v["systems"][0]["true_residual"].get<double>();
                    t.region = static_cast<int>(v["region"]["cells"].get<std::int64_t>());
                }
            }
        }
        const double floor = median(bare_setup) + median(bare_solve);
        if (rank == 0) {
            std::printf("\n### diffusion, %s %d³, %d rank(s), tolerance 1e-8, medians of %d\n\n", label.c_str(), N,
                        size, reps);
            std::printf("| N | ranks | solver | region cells | iterations | true residual | assemble s | setup s | solve s | (assemble + setup + solve) / bare | diffusion phase s | / bare | sources / region / flux / bands s |\n");
            std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
            std::printf("| %d | %d | bare hypre PFMG-PCG | | %d | | | %.3f | %.3f | 1.00 | %.3f | 1.00 | |\n", N,
                        size, bare_iterations, median(bare_setup), median(bare_solve), floor);
            for (size_t q = 0; q < solvers.size(); ++q) {
                const Times& t = times[q];
                if (!t.failure.empty()) {
                    std::printf("| %d | %d | %s | | failed: %.80s | | | | | | | | |\n", N, size, solvers[q].c_str(),
                                t.failure.c_str());
                    continue;
                }
                const double as = median(t.assemble), su = median(t.setup), so = median(t.solve), total = median(t.total);
                std::printf("| %d | %d | %s | %d | %d | %.1e | %.3f | %.3f | %.3f | %.2f | %.3f | %.2f | %.3f / %.3f / %.3f / %.3f |\n", N, size,
                            solvers[q].c_str(), t.region, t.iterations, t.residual, as, su, so, (as + su + so) / floor,
                            total, total / floor, median(t.sources), median(t.region_time), median(t.flux),
                            median(t.bands));
            }
        }
    } catch (const std::exception& e) {
        if (rank == 0) std::fprintf(stderr, "bench_diffusion: %s\n", e.what());
        status = 1;
    }
    MPI_Finalize();
    return status;
}
