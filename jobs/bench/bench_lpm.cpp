// Benchmark (not a test): light propagation maps on the default cumulus at N³, one band, the
// sun only, a fixed number of iterations (epsilon 0), on however many ranks it is started.
//   mpiexec -n 2 build/bin/bench_lpm N p iterations [k refinement repeats]
// Prints one markdown row: N, p x p, k, R, iterations, ranks, solve wall seconds and CPU
// seconds (max over ranks; medians of the repeats after one warm-up), CPU seconds per map
// sweep, CPU ns per ray step (ray x cell layer) = cpu x ranks / (iterations 6 N³ p² R²).
// On a shared machine wall time overstates; on a quiet one wall ≈ CPU + pipeline waits.
#include <mpi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <vector>

#include "io/scene/density_import.h"
#include "jobs/bench/bench_support.h"
#include "solvers/light/sun_transmittance.h"
#include "solvers/lpm/solve_band.h"
#include "src/core/log.h"
#include "src/core/mpi_init.h"

using namespace nimbus;
using bench::median;

// CPU seconds of this process (the machine may be shared: wall time then overstates).
static double cpu_seconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    log::init(rank, "warn");
    const int N = argc > 1 ? std::atoi(argv[1]) : 64;
    LpmOptions o;
    o.p = argc > 2 ? std::atoi(argv[2]) : 5;
    o.iterations = argc > 3 ? std::atoi(argv[3]) : 3;
    o.k = argc > 4 ? std::atoi(argv[4]) : 1;
    o.refinement = argc > 5 ? std::atoi(argv[5]) : 1;
    const int repeats = argc > 6 ? std::atoi(argv[6]) : 3;
    o.epsilon = 0.0;
    o.tail = "none";  // the map sweeps alone (the P1 tail is timed by nimbus run: model/lpm/solve)
    o.validate();

    Scene scene = bench::default_cloud_scene(N);
    const Decomposition d(MPI_COMM_WORLD, scene.grid.n);
    Medium medium = load_medium(scene, d);
    medium.bands.resize(1);  // one band
    const std::vector<DirectionalLight> sun{make_lights(scene)[0]};
    Report rep;
    const LightTransport lt = compute_light_transport(d, medium, sun, rep);
    const lpm::Angular ang(o.p, o.k);

    std::vector<double> t, tc;
    int iterations = 0;
    for (int r = 0; r < std::max(1, repeats + (repeats > 0 ? 1 : 0)); ++r) {
        MPI_Barrier(MPI_COMM_WORLD);
        const double t0 = MPI_Wtime(), c0 = cpu_seconds();
        const lpm::BandResult res = lpm::solve_band(d, medium, lt, 0, o, ang);
        MPI_Barrier(MPI_COMM_WORLD);
        double c = cpu_seconds() - c0;
        MPI_Allreduce(MPI_IN_PLACE, &c, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
        if (r > 0 || repeats == 0) {
            t.push_back(MPI_Wtime() - t0);
            tc.push_back(c);
        }
        iterations = res.iterations;
    }
    const double s = median(t), sc = median(tc);
    const double ray_steps = static_cast<double>(iterations) * 6.0 * N * N * N * o.p * o.p * o.refinement * o.refinement;
    if (rank == 0)
        std::printf("| %d³ | %d×%d | %d | %d | %d | %d | %.3f | %.3f | %.4f | %.2f |\n", N, o.p, o.p, o.k, o.refinement,
                    iterations, size, s, sc, sc / (6.0 * iterations), 1e9 * sc * size / ray_steps);
    MPI_Finalize();
    return 0;
}
