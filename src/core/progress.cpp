#include "src/core/progress.h"

#include <fmt/format.h>

#include <cmath>

#include "src/core/log.h"
#include "src/core/report.h"

namespace nimbus {

double progress_eta(double done, double total, double first_done, double first_time, double start, double now) {
    if (done > first_done && first_done >= 0) return (now - first_time) * (total - done) / (done - first_done);
    return done > 0 ? (now - start) * (total - done) / done : 0.0;
}

Progress::Progress(std::string what, double total, bool speaker, double quiet, double interval)
    : what_(std::move(what)), total_(total), start_(wall_time()), last_(start_),
      speaker_(speaker), quiet_(quiet), interval_(interval) {}

bool Progress::due() {
    if (!speaker_) return false;
    const double now = wall_time();
    if (now - start_ < quiet_ || now - last_ < interval_) return false;
    last_ = now;
    spoke_ = true;
    return true;
}

void Progress::update(double done) {
    if (speaker_ && first_done_ < 0) {
        first_done_ = done;
        first_time_ = wall_time();
    }
    if (!due()) return;
    const double frac = total_ > 0 ? done / total_ : 0.0;
    const double eta = progress_eta(done, total_, first_done_, first_time_, start_, last_);
    log::info("{}: {:5.1f}% ({:.1f} s elapsed, ETA {:.1f} s)", what_, 100.0 * frac, last_ - start_, eta);
}

void Progress::update(double done, double eta, const std::string& until, const std::string& detail) {
    if (!due()) return;
    const double frac = total_ > 0 ? done / total_ : 0.0;
    const std::string eta_text = std::isfinite(eta) ? fmt::format("ETA {:.1f} s", eta) : std::string("ETA unknown");
    log::info("{}: {:5.1f}% ({:.1f} s elapsed, {} at the {}){}", what_, 100.0 * frac, last_ - start_, eta_text, until,
              detail.empty() ? "" : "; " + detail);
}

void Progress::finish() {
    if (speaker_ && spoke_) log::info("{}: done in {:.1f} s", what_, wall_time() - start_);
}

}  // namespace nimbus
