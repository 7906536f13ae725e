// What the benchmarks (jobs/bench/*.cpp) share: medians, maxima over ranks, barrier-to-barrier
// timing, and the built-in default cloud resampled to N³ cells over the same 2.4 km domain.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "io/scene/scene_toml.h"

namespace nimbus::bench {

// The median (the mean of the middle two for an even count; 0 for none).
inline double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

inline double max_over_ranks(double v, MPI_Comm comm) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MAX, comm);
    return v;
}

// Seconds from a barrier before fn to a barrier after it (the slowest rank's time).
template <class Fn>
double timed(Fn&& fn, MPI_Comm comm = MPI_COMM_WORLD) {
    MPI_Barrier(comm);
    const double t0 = MPI_Wtime();
    fn();
    MPI_Barrier(comm);
    return MPI_Wtime() - t0;
}

// The built-in default scene (96 x 96 x 64 cells of 25 m) on an N³ grid with cells of 2400/N m,
// plus further overrides ("key=value", as nimbus run --set).
inline Scene default_cloud_scene(int N, std::vector<std::string> overrides = {}) {
    overrides.insert(overrides.begin(), {fmt::format("grid.n=[{},{},{}]", N, N, N),
                                         fmt::format("grid.cell_size={}", 25.0 * 96 / N)});
    return default_scene(overrides);
}

}  // namespace nimbus::bench
