#include "src/core/convergence_outlook.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nimbus {

ConvergenceOutlook convergence_outlook(const std::vector<double>& history, double tolerance) {
    constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
    const size_t n = history.size();
    if (n == 0) return {0.0, kUnknown};
    const double first = history.front(), last = history.back();
    if (last <= tolerance) return {1.0, 0.0};
    ConvergenceOutlook o;
    // On a log scale: 0 at the first change (or above it), 1 at the tolerance.
    o.fraction = first > tolerance && last < first ? std::log(first / last) / std::log(first / tolerance) : 0.0;
    const size_t m = std::min<size_t>(3, n - 1);  // ratios in the rate
    const double before = m > 0 ? history[n - 1 - m] : 0.0;
    const double rate = m > 0 && before > 0.0 ? std::pow(last / before, 1.0 / static_cast<double>(m)) : kUnknown;
    // ceil of the exact count; the 1e-9 keeps round-off (4.000000000000001) from adding one.
    o.remaining_iterations =
        rate > 0.0 && rate < 1.0 ? std::ceil(std::log(tolerance / last) / std::log(rate) - 1e-9) : kUnknown;
    return o;
}

RunOutlook run_outlook(const std::vector<double>& history, double tolerance, double seconds,
                       double first_seconds, int done, double done_seconds, int total) {
    const ConvergenceOutlook o = convergence_outlook(history, tolerance);
    RunOutlook r;
    r.fraction = total > 0 ? (done + o.fraction) / total : 0.0;
    const size_t n = history.size();
    const double per_iteration = n >= 2 ? (seconds - first_seconds) / static_cast<double>(n - 1)
                                         : n == 1 ? seconds : 0.0;
    double this_left = o.remaining_iterations * per_iteration;  // NaN stays NaN
    if (std::isnan(this_left) && done > 0) this_left = std::max(0.0, done_seconds / done - seconds);
    const double per_solve = done > 0 ? done_seconds / done : seconds + this_left;
    r.seconds_left = this_left + std::max(0, total - done - 1) * per_solve;
    return r;
}

}  // namespace nimbus
