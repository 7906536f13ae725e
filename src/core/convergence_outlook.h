// How far an iteration that converges geometrically toward a tolerance has come, and how long
// it will take: the progress lines of the iterative models (DOM's outer iterations, the flux
// limiter of diffusion). Pure functions of the history of relative changes.
#pragma once

#include <vector>

namespace nimbus {

// Where one solve stands, from its history of relative changes: the share of the way from the
// first change to the tolerance on a log scale (0..1; 1 once below it), and the iterations still
// needed at the geometric rate of the last three ratios of successive changes (fewer at the start;
// NaN when there is no rate yet or it is not below 1, i.e. the change is not falling). An
// iteration that stops on two changes in a row below the tolerance (the flux limiter) takes
// one more than this says.
struct ConvergenceOutlook {
    double fraction = 0.0;
    double remaining_iterations = 0.0;
};
ConvergenceOutlook convergence_outlook(const std::vector<double>& history, double tolerance);

// Progress over `total` solves: `done` solves are complete and took `done_seconds`; the current
// one has run `seconds` for history.size() iterations, the first of which ended at
// `first_seconds` (so its set-up, which the first iteration carries, is not taken for an
// iteration's cost). fraction: (done + the current one's outlook fraction) / total.
// seconds_left: the current solve's remaining iterations at the mean time of its iterations
// after the first (of the first alone while there is one), plus each later solve at the mean
// time of the completed ones (of the current one's projected total when none is complete).
// Where the current solve's remaining iterations are unknown, it is taken to last as long as
// the completed ones did on average; with none complete either, seconds_left is NaN.
struct RunOutlook {
    double fraction = 0.0;
    double seconds_left = 0.0;
};
RunOutlook run_outlook(const std::vector<double>& history, double tolerance, double seconds,
                       double first_seconds, int done, double done_seconds, int total);

}  // namespace nimbus
