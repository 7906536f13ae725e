#include "src/cmd/memory.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "src/core/error.h"
#include "solvers/registry.h"
#include "src/physics/lights.h"
#include "src/render/ground.h"

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
    const int nlights = static_cast<int>(make_lights(s).size());
    // The light pass's tau per light term, density, the per-band outputs, the renderer's view
    // volume and image; plus ~40 MiB of libraries and MPI that every rank holds (a 48x48x32
    // single-scattering run peaks at 53 MiB for ~15 MiB of fields).
    const double fields = 1 + nlights + 2.0 * s.nbands() + 2.0;
    MemoryEstimate m{40.0 * 1024 * 1024 + local_cells * 8 * fields + 40.0 * s.camera.width * s.camera.height,
                     "light pass, render"};
    // A shadowed ground gathers the outer cell layers of the density and of every light's tau
    // on every rank (render/ground.h), and one field's more while it gathers.
    if (s.background.kind == BackgroundSpec::Kind::ground && s.render.mode != RenderMode::single_unshadowed) {
        m.bytes += (nlights + 2.0) * GroundShading::outer_layer_values(s.grid.n) * 8;
        m.what += ", ground shadows";
    }
    const double model = make_model(s.model)->memory_bytes(s, d, nlights);
    m.replicated = s.model.name == "montecarlo";
    if (model > 0) {
        m.bytes += model;
        m.what += fmt::format(", model {} {:.0f} MiB", s.model.name, model / (1024.0 * 1024.0));
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
                                 "{}",
                                 m.bytes / kGiB, m.what, node_bytes / kGiB, ranks_on_node, avail / kGiB,
                                 m.replicated ? "Monte Carlo copies the grid to every rank: run fewer ranks per node "
                                                "(more nodes), or a coarser grid"
                                              : "use more ranks (on more nodes) or a smaller grid"));
}

}  // namespace nimbus::cmd
