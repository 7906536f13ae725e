// Benchmark (not a test): the floor of the Monte Carlo path kernels. The production kernels
// (trace_photons, trace_light.h, one path at a time; trace_photons_lanes, trace_lanes.h, eight
// paths in the lanes of AVX-512 vectors: implicit capture, roulette, HG scattering, the exact
// grid walk with a track-length tally into the voxels) trace the photons of a volume source
// filling a small periodic homogeneous grid that stays in L1/L2, so no cache miss and no empty
// cell slows them down. Varying the extinction per cell varies the cell segments per
// collision; a least-squares line through the rows splits each kernel's cost into a fixed part
// per collision (scattering, flight set-up) and a part per segment.
//   build/bin/bench_montecarlo [N [collisions]]        (defaults 16, 4000000)
// Prints a markdown table and the fits; single process, no MPI. The lane columns are left out
// on a CPU without AVX-512.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "solvers/montecarlo/emitter.h"
#include "solvers/montecarlo/trace_lanes.h"
#include "solvers/montecarlo/trace_light.h"
#include "src/core/empty_space.h"
#include "src/core/grid_walk.h"

using namespace nimbus;
using namespace nimbus::mc;

namespace {

struct Row {
    double ns_per_collision, segments_per_collision;
};

// Photons of the source until about `collisions` are done (two rounds: the first estimates the
// collisions per photon), with one kernel.
template <class Kernel>
Row run(GridView g, std::int64_t collisions, Kernel&& kernel) {
    std::vector<std::int64_t> lit;
    PathTally probe;
    kernel(g, 0, 2000, lit, probe);
    const auto photons = static_cast<std::int64_t>(static_cast<double>(collisions) * 2000.0 /
                                                   static_cast<double>(std::max<std::int64_t>(1, probe.collisions)));
    PathTally out;
    lit.clear();
    const auto t0 = std::chrono::steady_clock::now();
    kernel(g, 2000, 2000 + photons, lit, out);
    const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto c = static_cast<double>(out.collisions);
    return {dt / c * 1e9, static_cast<double>(out.segments) / c};
}

// ns per collision = fixed + per_segment x segments (least squares over the rows).
void print_fit(const char* name, const std::vector<Row>& rows, int N) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const Row& r : rows) {
        sx += r.segments_per_collision, sy += r.ns_per_collision;
        sxx += r.segments_per_collision * r.segments_per_collision;
        sxy += r.segments_per_collision * r.ns_per_collision;
    }
    const double n = static_cast<double>(rows.size());
    const double per_segment = (n * sxy - sx * sy) / (n * sxx - sx * sx), fixed = (sy - per_segment * sx) / n;
    std::printf("fit, %s kernel (%d³ periodic grid, cache-resident): %.1f ns per collision + %.2f ns per cell segment\n",
                name, N, fixed, per_segment);
}

}  // namespace

int main(int argc, char** argv) {
    const int N = argc > 1 ? std::atoi(argv[1]) : 16;
    const std::int64_t collisions = argc > 2 ? std::atoll(argv[2]) : 4000000;
    const bool lanes = lane_kernel_supported();
    const PhotonOptics optics{0.999, 0.85, 0.05};
    std::printf("| extinction per cell | cell segments per collision | scalar ns per collision |%s\n| --- | --- | --- |%s\n",
                lanes ? " lanes ns per collision | lanes speed-up |" : "", lanes ? " --- | --- |" : "");
    std::vector<Row> scalar_rows, lane_rows;
    for (const double kappa : {3.0, 1.0, 0.3, 0.1, 0.03}) {
        const std::vector<float> k(static_cast<size_t>(N) * N * N, static_cast<float>(kappa));
        VoxelGrid grid = make_voxels({N, N, N}, k);
        const GridView g = grid.view({true, true, true});
        const VolumeEmitter source({1.0}, Box{{0, 0, 0}, {N, N, N}}, [](int, int, int) { return 1.0; }, 1.0);
        const LightTerm term{nullptr, Vec3{0, 0, -1}, &source, 0, 1.0};
        scalar_rows.push_back(run(g, collisions, [&](const GridView& v, std::int64_t lo, std::int64_t hi,
                                                     std::vector<std::int64_t>& lit, PathTally& out) {
            trace_photons(v, optics, term, 1, lo, hi, false, nullptr, lit, out);
        }));
        std::printf("| %.2f | %.2f | %.1f |", kappa, scalar_rows.back().segments_per_collision,
                    scalar_rows.back().ns_per_collision);
        if (lanes) {
            lane_rows.push_back(run(g, collisions, [&](const GridView& v, std::int64_t lo, std::int64_t hi,
                                                       std::vector<std::int64_t>& lit, PathTally& out) {
                trace_photons_lanes(v, optics, term, 1, lo, hi, lit, out);
            }));
            std::printf(" %.1f | %.2f |", lane_rows.back().ns_per_collision,
                        scalar_rows.back().ns_per_collision / lane_rows.back().ns_per_collision);
        }
        std::printf("\n");
    }
    std::printf("\n");
    print_fit("scalar", scalar_rows, N);
    if (lanes) print_fit("lanes", lane_rows, N);
    return 0;
}
