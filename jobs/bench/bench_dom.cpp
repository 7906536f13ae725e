// Benchmark of the discrete-ordinates sweep (solvers/dom): grind time in LLNL Kripke's
// definition, total iteration time / (zones x directions x groups x iterations), in ns.
//
//   mpiexec -n 2 ./bench_dom 64 cube96|S<n> [iterations=5] [legendre=4] [tile_rows=8] [octant_overlap=8]
//   (jobs/bench_dom.sh runs the table: 32³-96³, S8, S16, cube96; 1 and 2 ranks)
//
// Problem (Kripke-like): a homogeneous cube of N³ unit cells, sigma_t such that the cube is 10
// mean free paths wide, albedo 0.9, isotropic scattering expanded to Legendre order L (default
// 4, (L+1)² = 25 moments, Kripke's default), vacuum boundaries, one band, a volume source;
// plain source iteration (no DSA) for a fixed number of iterations after one warm-up
// iteration. Columns: time per iteration, grind time (whole iteration: moments-to-directions,
// sweep, directions-to-moments), the sweep alone, pipeline efficiency of the sweep
// (1 - time blocked on upstream planes / sweep time, min over ranks), model state per cell.
// Times are the max over ranks. Prints one markdown row on rank 0.
#include <mpi.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "jobs/bench/bench_support.h"
#include "solvers/dom/angular_set.h"
#include "solvers/dom/band_problem.h"
#include "solvers/dom/iteration.h"
#include "solvers/dom/transport_sweep.h"
#include "src/core/error.h"
#include "src/core/mpi_init.h"
#include "src/scene/medium.h"

namespace {

using namespace nimbus;
using bench::max_over_ranks;

int run(int argc, char** argv) {
    const int n = argc > 1 ? std::atoi(argv[1]) : 32;
    const std::string quad = argc > 2 ? argv[2] : "cube96";
    const int iterations = argc > 3 ? std::atoi(argv[3]) : 5;
    const int L = argc > 4 ? std::atoi(argv[4]) : 4;
    const int tile_rows = argc > 5 ? std::atoi(argv[5]) : 8;
    const int overlap = argc > 6 ? std::atoi(argv[6]) : DomOptions{}.octant_overlap;
    DomOptions o;
    if (quad == "cube96") {
        o.quadrature = "cube96";
    } else if (quad.size() > 1 && quad[0] == 'S' &&
               quad.find_first_not_of("0123456789", 1) == std::string::npos) {
        o.quadrature = "level-symmetric";
        o.order = std::atoi(quad.c_str() + 1);
    } else {
        throw Error("quadrature '" + quad + "': cube96 or S<order> (level-symmetric, e.g. S8)");
    }
    if (n < 1 || iterations < 1 || L < 0 || tile_rows < 1 || overlap < 1)
        throw Error("N, iterations, tile_rows and octant_overlap must be >= 1 and legendre >= 0");
    o.legendre_order = L;
    o.tile_rows = tile_rows;
    o.octant_overlap = overlap;
    o.validate();
    const Decomposition d(MPI_COMM_WORLD, {n, n, n});
    Medium m;
    m.grid.n = {n, n, n};
    m.grid.h = 1.0;
    m.rho = Field<double>(d.local(), 1, 1, 1.0);
    m.bands = {BandOptics{"gray", 10.0 / n, 0.9, 0.0}};
    const dom::AngularSet ang = dom::make_angular_set(o);
    dom::BandProblem p = dom::make_band_optics(m, 0, d.local(), ang, false);
    p.emission.fill(1.0);
    dom::add_light_sources(p, d, m, LightTransport{}, 0, ang);
    sweep::SweepOptions sopt;
    sopt.tile_rows = tile_rows;
    sopt.octant_overlap = overlap;
    Report report;
    dom::SweepOutput out;
    {
        dom::TransportSweeper warm(d, ang, m.grid.h, sopt, 1e-8);
        dom::iterate_band(d, warm, ang, p, "source", 1e-300, 1, out, report);
    }
    dom::TransportSweeper sweeper(d, ang, m.grid.h, sopt, 1e-8);
    const auto r = dom::iterate_band(d, sweeper, ang, p, "source", 1e-300, iterations, out, report);
    const auto& t = sweeper.timing();
    const double total = max_over_ranks(r.seconds, d.comm());
    const double sweep_s = max_over_ranks(t.sweep_seconds, d.comm());
    const double moment_s = max_over_ranks(t.moment_seconds, d.comm());
    double eff = t.sweep_seconds > 0 ? 1.0 - t.wait_seconds / t.sweep_seconds : 1.0;
    MPI_Allreduce(MPI_IN_PLACE, &eff, 1, MPI_DOUBLE, MPI_MIN, d.comm());
    const double unknowns = static_cast<double>(d.global().cells()) * ang.quadrature.size() * r.iterations;
    // moments, source moments and phi of the previous iteration; psi and source per octant in flight
    const double bytes = 8.0 * (3 * ang.nmom + 2 * overlap * ang.max_octant_size + 8);
    if (d.rank() == 0)
        std::printf("| %d³ | %s | %d | %d | %d | %d | %d | %d | %.3f | %.2f | %.2f | %.2f | %.2f | %.0f |\n", n,
                    quad.c_str(), ang.quadrature.size(), ang.nmom, d.size(), tile_rows, overlap, r.iterations,
                    total / r.iterations,
                    1e9 * total / unknowns, 1e9 * sweep_s / unknowns, 1e9 * moment_s / unknowns, eff, bytes);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    nimbus::init_mpi(&argc, &argv);
    int rc = 0;
    try {
        rc = run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_dom: %s\n", e.what());
        rc = 1;
    }
    MPI_Finalize();
    return rc;
}
