#include "src/cmd/memory.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "src/core/error.h"
#include "src/physics/lights.h"

namespace nimbus::cmd {
namespace {

constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;

// Bytes this process could still allocate: MemAvailable of /proc/meminfo, capped by the cgroup
// (v2) limit; 0 when unknown (not Linux).
double available_memory() {
    double avail = 0;
    std::ifstream meminfo("/proc/meminfo");
    for (std::string line; std::getline(meminfo, line);) {
        std::istringstream in(line);
        std::string key;
        double kib = 0;
        if (in >> key >> kib && key == "MemAvailable:") avail = kib * 1024.0;
    }
    std::ifstream max_file("/sys/fs/cgroup/memory.max"), cur_file("/sys/fs/cgroup/memory.current");
    double limit = 0, used = 0;
    if (max_file >> limit && cur_file >> used && limit > used)  // "max" (no limit) does not parse
        avail = avail > 0 ? std::min(avail, limit - used) : limit - used;
    return avail;
}

}  // namespace

MemoryEstimate estimate_memory(const Scene& s, const Decomposition& d) {
    const double local_cells = static_cast<double>(d.local().grown(1).cells());
    const double nlights = static_cast<double>(make_lights(s).size());
    const double fields = 1 + nlights + 2.0 * s.nbands() + 2.0;
    MemoryEstimate m{local_cells * 8 * fields + 40.0 * s.camera.width * s.camera.height, "light pass, render"};
    if (s.model.name == "montecarlo") {
        // The density is replicated on every rank with per-band sum/sum² tallies (batch means).
        m.bytes += static_cast<double>(d.global().cells()) * (24.0 + 28.0 * s.nbands());
        m.what += ", Monte Carlo (replicated grid)";
    } else if (s.model.name == "diffusion") {
        // hypre: 7-point matrix + ~6 vectors, x ~1.4 for the multigrid hierarchy; flux per band.
        m.bytes += local_cells * 8 * (13 * 1.4 + 3.0 * s.nbands());
        m.what += ", diffusion (hypre)";
    }
    return m;
}

void check_memory_fits(MPI_Comm comm, const MemoryEstimate& m) {
    MPI_Comm node = MPI_COMM_NULL;
    MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
    int ranks_on_node = 1;
    MPI_Comm_size(node, &ranks_on_node);
    double node_bytes = 0;
    MPI_Allreduce(&m.bytes, &node_bytes, 1, MPI_DOUBLE, MPI_SUM, node);
    MPI_Comm_free(&node);
    const double avail = available_memory();
    check_collective(comm, avail <= 0 || node_bytes <= avail,
                     fmt::format("the grid does not fit in memory: a run needs about {:.1f} GiB per rank ({}), "
                                 "{:.1f} GiB for the {} rank(s) on this node, which has {:.1f} GiB available; "
                                 "use more ranks (on more nodes) or a smaller grid",
                                 m.bytes / kGiB, m.what, node_bytes / kGiB, ranks_on_node, avail / kGiB));
}

}  // namespace nimbus::cmd
