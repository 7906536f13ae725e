// Benchmark (not a test): the floor of the Monte Carlo path kernel. The production kernel
// (photon.h scatter_path: implicit capture, roulette, HG scattering, the exact grid walk with a
// track-length tally into the voxels) runs on a small periodic homogeneous grid that stays in
// L1/L2, so no cache miss and no empty cell slows it down. Varying the extinction per cell
// varies the cell segments per collision; a least-squares line through the rows splits the
// cost into a fixed part per collision (scattering, flight set-up) and a part per segment.
//   build/bin/bench_montecarlo [N [collisions]]        (defaults 16, 4000000)
// Prints a markdown table and the fit; single process, no MPI.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "src/core/empty_space.h"
#include "src/core/grid_walk.h"
#include "solvers/montecarlo/photon.h"

using namespace nimbus;
using namespace nimbus::mc;

namespace {

struct Row {
    double kappa, ns_per_collision, segments_per_collision;
};

// Paths of the production kernel on g until `collisions` are done (cloned like trace_light.cpp).
__attribute__((target_clones("arch=x86-64-v3", "default")))
Row run(GridView g, double kappa, std::int64_t collisions) {
    const PhotonOptics optics{0.999, 0.85, 0.05};
    Voxel* voxel = g.voxel;
    std::int64_t segments = 0;
    PathTally out;
    const auto t0 = std::chrono::steady_clock::now();
    for (std::uint64_t p = 0; out.collisions < collisions; ++p) {
        PathRng rng(1, 0, p);
        PathState s;
        s.idx = g.index({g.n[0] / 2, g.n[1] / 2, g.n[2] / 2});
        s.frac = {rng.uniform(), rng.uniform(), rng.uniform()};
        s.d = Vec3{0.0, 0.0, -1.0};
        scatter_path(g, optics, rng, s, out, 1.0, [&](std::int64_t idx, double wl) {
            ++segments;
            voxel[idx].tally += wl;
        });
    }
    const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto c = static_cast<double>(out.collisions);
    return {kappa, dt / c * 1e9, static_cast<double>(segments) / c};
}

}  // namespace

int main(int argc, char** argv) {
    const int N = argc > 1 ? std::atoi(argv[1]) : 16;
    const std::int64_t collisions = argc > 2 ? std::atoll(argv[2]) : 4000000;
    std::printf("| extinction per cell | cell segments per collision | ns per collision |\n| --- | --- | --- |\n");
    std::vector<Row> rows;
    for (const double kappa : {3.0, 1.0, 0.3, 0.1, 0.03}) {
        const std::vector<float> k(static_cast<size_t>(N) * N * N, static_cast<float>(kappa));
        VoxelGrid grid = make_voxels({N, N, N}, k);
        rows.push_back(run(grid.view({true, true, true}), kappa, collisions));
        std::printf("| %.2f | %.2f | %.1f |\n", rows.back().kappa, rows.back().segments_per_collision,
                    rows.back().ns_per_collision);
    }
    // ns per collision = fixed + per_segment x segments (least squares)
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const Row& r : rows) {
        sx += r.segments_per_collision, sy += r.ns_per_collision;
        sxx += r.segments_per_collision * r.segments_per_collision;
        sxy += r.segments_per_collision * r.ns_per_collision;
    }
    const double n = static_cast<double>(rows.size());
    const double per_segment = (n * sxy - sx * sy) / (n * sxx - sx * sx), fixed = (sy - per_segment * sx) / n;
    std::printf("\nfit (%d³ periodic grid, cache-resident): %.1f ns per collision + %.2f ns per cell segment\n", N,
                fixed, per_segment);
    return 0;
}
