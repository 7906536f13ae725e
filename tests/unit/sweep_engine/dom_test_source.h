// What both DOM sweep tests use (dom_overlap_test.cpp, dom_source_rows_test.cpp): a source
// of fields kappa, moments (every cell, no ghost layer) and one first-collision amplitude, with
// a phase value per direction that favours downward directions, as a sun overhead would; and the
// relative difference of two fields.
#pragma once

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <span>

#include "solvers/dom/angular_set.h"
#include "solvers/dom/transport_sweep.h"

namespace nimbus::dom::test_source {

inline SweepSource make(const AngularSet& ang, const Field<double>& kappa, const Field<double>& moments,
                        const Field<double>& amp) {
    SweepSource src;
    src.kappa = &kappa;
    src.moments = std::span<const double>(moments.data(), moments.size());  // every cell (no ghosts)
    src.amp = &amp;
    src.nl = 1;
    for (int o = 0; o < 8; ++o) {
        const auto& oc = ang.octants[static_cast<size_t>(o)];
        auto& P = src.light_phase[static_cast<size_t>(o)];
        for (int n = 0; n < oc.size(); ++n) P.push_back(0.05 + 0.1 * std::max(0.0, -oc.dir[static_cast<size_t>(n)].z));
    }
    return src;
}

// Largest |a - b| over owned cells and components, relative to max |scale| (max over ranks).
inline double rel_diff(const Field<double>& a, const Field<double>& b, const Field<double>& scale, MPI_Comm comm) {
    double v[2] = {0.0, 0.0};
    for_each_cell(a.owned(), [&](int i, int j, int k) {
        for (int c = 0; c < a.ncomp(); ++c) v[0] = std::max(v[0], std::abs(a(i, j, k, c) - b(i, j, k, c)));
        for (int c = 0; c < scale.ncomp(); ++c) v[1] = std::max(v[1], std::abs(scale(i, j, k, c)));
    });
    MPI_Allreduce(MPI_IN_PLACE, v, 2, MPI_DOUBLE, MPI_MAX, comm);
    return v[0] / v[1];
}

}  // namespace nimbus::dom::test_source
