// Progress with ETA for long phases. Rank 0 logs at most every `interval` seconds and only
// once the phase has run longer than `quiet` seconds, so short phases stay silent.
#pragma once

#include <string>

namespace nimbus {

// Seconds left of a phase of `total` units with `done` complete at time `now`: at the rate since
// the first report (`first_done` units at `first_time`) once there is one more unit, else at the
// mean rate since `start`; 0 before any unit is done.
double progress_eta(double done, double total, double first_done, double first_time, double start, double now);

class Progress {
public:
    Progress(std::string what, double total, bool speaker, double quiet = 2.0, double interval = 2.0);
    // Reports that `done` units of `total` are complete (not collective). The ETA is the rate
    // since the first call, which carries the phase's set-up (LPM's first map sweep took the
    // source's set-up with it and the first line said 1.9x the time left), from the second on.
    void update(double done);
    // The same with the caller's ETA, for phases that may stop before `total` (a time budget,
    // a target error, a tolerance): `eta` seconds to the stop named by `until` ("time budget",
    // ...; not finite: "ETA unknown"), and `detail` (if any) after the figures.
    void update(double done, double eta, const std::string& until, const std::string& detail = {});
    void finish();

private:
    bool due();  // rank 0, past the quiet time and the interval since the last line: marks it spoken
    std::string what_;
    double total_, start_, last_;
    bool speaker_, spoke_ = false;
    double first_done_ = -1.0, first_time_ = 0.0;  // the first update(done)'s units and time
    double quiet_, interval_;
};

}  // namespace nimbus
