// Benchmark (not a test) of the psf model on the default cumulus at N³ and a W×H image, on
// however many ranks it is started:
//   mpiexec -n 2 build/bin/bench_psf 128 1920 1080 [repeats]
// Times (medians of `repeats`, after one warm-up): the light-volume pyramid alone (every light
// term's T_l, Algorithm 1 BuildVolumePyramid), the whole psf preprocessing (pyramid + the light
// pass on the medium indicator for s2), the single-scattering render and the psf render of the
// same image. Prints one markdown row. A 5th argument `single` or `psf` runs only that render
// (once, no warm-up; a 6th argument sets model.psf.step_growth) after the set-up, for instruction counts with `perf stat -e instructions`;
// `setup` runs only the set-up (the baseline to subtract).
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

#include "io/scene/density_import.h"
#include "jobs/bench/bench_support.h"
#include "solvers/light/sun_transmittance.h"
#include "solvers/psf/psf_source.h"
#include "src/core/log.h"
#include "src/core/mpi_init.h"
#include "src/model/model.h"
#include "src/render/raycaster.h"

using namespace nimbus;
using bench::median;
using bench::timed;

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    log::init(rank, "warn");
    const int N = argc > 1 ? std::atoi(argv[1]) : 128;
    const int W = argc > 2 ? std::atoi(argv[2]) : 1920, H = argc > 3 ? std::atoi(argv[3]) : 1080;
    const int repeats = argc > 4 ? std::atoi(argv[4]) : 3;
    const std::string only = argc > 5 ? argv[5] : "";
    {
        Scene scene = bench::default_cloud_scene(N, {fmt::format("camera.resolution=[{},{}]", W, H)});
        const Decomposition d(MPI_COMM_WORLD, scene.grid.n);
        const Medium medium = load_medium(scene, d);
        const auto lights = make_lights(scene);
        Report rep;
        const LightTransport lt = compute_light_transport(d, medium, lights, rep, {}, scene.light.method);
        const SolveContext ctx{scene, d, medium, lt, rep};
        const int nl = static_cast<int>(lights.size());

        if (!only.empty()) {
            const DiffuseSolution none;
            Report rr;
            RenderInputs in{scene, medium, lt, none};
            PsfOptions opt;
            if (argc > 6) opt.step_growth = std::atof(argv[6]);
            psf::PsfSource src(ctx, opt);
            if (only == "psf") in.view_source = &src;
            if (only != "setup") {
                const std::clock_t c0 = std::clock();
                render_image(in, d, rr);
                const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
                double cpu_max = 0.0;
                MPI_Reduce(&cpu, &cpu_max, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
                if (rank == 0) std::printf("%s render: %.3f s CPU (max over %d ranks)\n", only.c_str(), cpu_max, size);
            }
            MPI_Finalize();
            return 0;
        }
        std::vector<double> t_pyr, t_pre, t_single, t_psf;
        for (int r = 0; r < repeats + 1; ++r) {
            const double t = timed([&] {
                Field<double> level0(d.local(), 3, nl, 0.0);
                for_each_cell(d.local(), [&](int i, int j, int k) {
                    for (int l = 0; l < nl; ++l)
                        level0(i, j, k, l) = std::exp(-scene.bands[0].sigma_t * lt.tau_rho[static_cast<size_t>(l)](i, j, k));
                });
                const psf::LightPyramid p(std::move(level0), medium.grid, d, 0);
            });
            if (r > 0) t_pyr.push_back(t);
        }
        std::unique_ptr<psf::PsfSource> src;
        for (int r = 0; r < repeats + 1; ++r) {
            const double t = timed([&] { src = std::make_unique<psf::PsfSource>(ctx, PsfOptions{}); });
            if (r > 0) t_pre.push_back(t);
        }
        const DiffuseSolution none;
        for (int r = 0; r < repeats + 1; ++r) {
            Report rr;
            const double t = timed([&] { render_image(RenderInputs{scene, medium, lt, none}, d, rr); });
            if (r > 0) t_single.push_back(t);
        }
        for (int r = 0; r < repeats + 1; ++r) {
            Report rr;
            RenderInputs in{scene, medium, lt, none};
            in.view_source = src.get();
            const double t = timed([&] { render_image(in, d, rr); });
            if (r > 0) t_psf.push_back(t);
        }
        if (rank == 0)
            std::printf("| %d³ | %d×%d | %d | %d | %.3f | %.3f | %.3f | %.3f | %.2f |\n", N, W, H, size, nl,
                        median(t_pyr), median(t_pre), median(t_single), median(t_psf),
                        median(t_psf) / median(t_single));
    }
    MPI_Finalize();
    return 0;
}
