// The source both DOM sweep tests use (dom_overlap_test.cpp, dom_source_rows_test.cpp): fields
// kappa, moments (every cell, no ghost layer) and one first-collision amplitude, and a phase value per direction that favours
// downward directions, as a sun overhead would.
#pragma once

#include <algorithm>
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

}  // namespace nimbus::dom::test_source
