#include "src/core/report.h"

#include "src/core/bcast.h"
#include "src/core/mpi_init.h"

#include <sys/resource.h>

#include <algorithm>

namespace nimbus {
namespace {
thread_local std::vector<std::string> timer_stack;
}

void Report::add_time(const std::string& name, double seconds) {
    auto it = std::find_if(times_.begin(), times_.end(), [&](auto& p) { return p.first == name; });
    if (it == times_.end()) times_.emplace_back(name, seconds); else it->second += seconds;
}

double Report::time(const std::string& name) const {
    for (auto& [n, t] : times_) if (n == name) return t;
    return 0.0;
}

nlohmann::json Report::summarize(MPI_Comm comm) const {
    int rank = 0, size = 1;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    // Rank 0's phase list defines the order; every rank reduces over the same names.
    std::string names;
    for (auto& [n, t] : times_) names += n + '\n';
    names = bcast_string(comm, 0, names);
    std::vector<std::string> order;
    for (size_t p = 0, q; (q = names.find('\n', p)) != std::string::npos; p = q + 1)
        order.push_back(names.substr(p, q - p));
    std::vector<double> mine(order.size()), maxv(order.size());
    for (size_t i = 0; i < order.size(); ++i) mine[i] = time(order[i]);
    MPI_Allreduce(mine.data(), maxv.data(), static_cast<int>(mine.size()), MPI_DOUBLE, MPI_MAX, comm);
    double mem = static_cast<double>(peak_memory_bytes());
    std::vector<double> mems(static_cast<size_t>(size));
    MPI_Allgather(&mem, 1, MPI_DOUBLE, mems.data(), 1, MPI_DOUBLE, comm);

    nlohmann::json out;
    nlohmann::json phases = nlohmann::json::array();
    for (size_t i = 0; i < order.size(); ++i)
        phases.push_back({{"name", order[i]}, {"seconds", maxv[i]}});
    out["phases"] = phases;
    out["peak_memory_bytes_per_rank"] = mems;
    out["ranks"] = size;
    if (!mpi_io_choice().empty()) out["mpi_io"] = mpi_io_choice();  // mpi_init.h
    // Values are rank 0's (they may differ per rank): broadcast so every rank returns the same
    // JSON, which collective writers (HDF5 attributes) require.
    out["values"] = nlohmann::json::parse(bcast_string(comm, 0, rank == 0 ? values_.dump() : std::string()));
    return out;
}

ScopedTimer::ScopedTimer(Report& report, const std::string& name)
    : report_(report),
      name_(timer_stack.empty() ? name : timer_stack.back() + "/" + name),
      start_(wall_time()) {
    timer_stack.push_back(name_);
}

ScopedTimer::~ScopedTimer() {
    timer_stack.pop_back();
    report_.add_time(name_, elapsed());
}

double ScopedTimer::elapsed() const { return wall_time() - start_; }

std::size_t peak_memory_bytes() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<std::size_t>(u.ru_maxrss) * 1024;  // Linux: kilobytes
}

}  // namespace nimbus
