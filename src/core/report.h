// Run report: per-phase wall times (hierarchical names, "render/composite"), counters
// (iterations, residuals, sizes) and peak memory. One ScopedTimer type feeds it; the report
// is logged at the end of a run and stored in the HDF5 output.
#pragma once

#include <mpi.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace nimbus {

class Report {
public:
    // Adds `seconds` to phase `name` (nested names use '/').
    void add_time(const std::string& name, double seconds);
    // Free-form values a phase reports: iterations, residual history, problem size, ...
    nlohmann::json& values() { return values_; }
    const nlohmann::json& values() const { return values_; }
    double time(const std::string& name) const;

    // Collective: max over ranks of every phase time, peak memory of every rank, and rank 0's
    // values; returns the same JSON on every rank. Phases absent on some ranks count as 0 there.
    nlohmann::json summarize(MPI_Comm comm) const;

private:
    std::vector<std::pair<std::string, double>> times_;  // in first-seen order
    nlohmann::json values_ = nlohmann::json::object();
};

// Times a scope into report under `name`; nested timers prefix their parent's name.
class ScopedTimer {
public:
    ScopedTimer(Report& report, const std::string& name);
    ~ScopedTimer();
    ScopedTimer(const ScopedTimer&) = delete;
    ScopedTimer& operator=(const ScopedTimer&) = delete;
    double elapsed() const;

private:
    Report& report_;
    std::string name_;
    double start_;
};

// Wall clock in seconds (MPI_Wtime).
inline double wall_time() { return MPI_Wtime(); }
// Peak resident memory of this process in bytes (getrusage).
std::size_t peak_memory_bytes();

}  // namespace nimbus
