// Benchmark (not a test): times the light pass (sun + sky terms; the `sweep` and the `exact`
// method, alternating) and the single-scattering render (lit by the sweep's light) of the
// default cumulus at N³ and a W×H image, on however many ranks it is started.
//   mpiexec -n 2 build/bin/bench_foundation 256 1920 1080 [repeats]
// Prints one markdown row: N, ranks, light terms, light-pass seconds (sweep, exact), render
// seconds (medians).
#include <mpi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "io/scene/density_import.h"
#include "jobs/bench/bench_support.h"
#include "solvers/light/sun_transmittance.h"
#include "src/core/log.h"
#include "src/core/mpi_init.h"
#include "src/model/model.h"
#include "src/render/raycaster.h"

using namespace nimbus;
using bench::median;

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    log::init(rank, "warn");
    const int N = argc > 1 ? std::atoi(argv[1]) : 128;
    const int W = argc > 2 ? std::atoi(argv[2]) : 1920, H = argc > 3 ? std::atoi(argv[3]) : 1080;
    const int repeats = argc > 4 ? std::atoi(argv[4]) : 3;

    Scene scene = bench::default_cloud_scene(N, {fmt::format("camera.resolution=[{},{}]", W, H)});
    const Decomposition d(MPI_COMM_WORLD, scene.grid.n);
    const Medium medium = load_medium(scene, d);
    const auto lights = make_lights(scene);

    std::vector<double> t_light, t_exact, t_render;
    LightTransport lt;
    for (int r = 0; r < repeats + 1; ++r) {  // first repeat warms up (page-in), not counted
        for (const auto method : {LightSpec::Method::exact, LightSpec::Method::sweep}) {
            Report rep;
            MPI_Barrier(MPI_COMM_WORLD);
            double t0 = MPI_Wtime();
            lt = compute_light_transport(d, medium, lights, rep, {}, method);
            MPI_Barrier(MPI_COMM_WORLD);
            if (r > 0) (method == LightSpec::Method::sweep ? t_light : t_exact).push_back(MPI_Wtime() - t0);
        }
    }
    const DiffuseSolution diffuse = zero_solution(d, medium.nbands());
    for (int r = 0; r < repeats + 1; ++r) {
        Report rep;
        MPI_Barrier(MPI_COMM_WORLD);
        double t0 = MPI_Wtime();
        const Image img = render_image(RenderInputs{scene, medium, lt, diffuse}, d, rep);
        MPI_Barrier(MPI_COMM_WORLD);
        if (r > 0) t_render.push_back(MPI_Wtime() - t0);
    }
    if (rank == 0)
        std::printf("| %d³ | %d×%d | %d | %zu | %.3f | %.3f | %.3f |\n", N, W, H, size, lights.size(),
                    median(t_light), median(t_exact), median(t_render));
    MPI_Finalize();
    return 0;
}
