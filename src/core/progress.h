// Progress with ETA for long phases. Rank 0 logs at most every `interval` seconds and only
// once the phase has run longer than `quiet` seconds, so short phases stay silent.
#pragma once

#include <string>

namespace nimbus {

class Progress {
public:
    Progress(std::string what, double total, bool speaker, double quiet = 2.0, double interval = 2.0);
    // Reports that `done` units of `total` are complete (not collective).
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
    double quiet_, interval_;
};

}  // namespace nimbus
