#include "src/cmd/memory.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
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
    // volume (floats: rho and J per band, or with shadowed lights rho and Jd, A, ln T per band,
    // in groups of 4 with 3 bands; view_volume.h) and image; plus ~40 MiB of libraries and MPI
    // that every rank holds (a 48x48x32 single-scattering run peaks at 53 MiB for ~15 MiB of
    // fields).
    const int nb = s.nbands();
    const bool split = s.render.mode == RenderMode::scattering && nlights > 0;
    const double view_floats = split ? (nb == 3 ? 12.0 : 1.0 + 3.0 * nb) : 1.0 + nb;
    const double fields = 1 + nlights + 2.0 * nb + view_floats / 2.0;
    // The image: every rank's fragments and the compositing buffers of its rows, and rank 0's
    // whole image and its outputs; rank 0's share on every rank (the same figure for every rank
    // keeps `info --ranks N` equal to a run's). A shaded ground adds a fragment to every pixel
    // that sees it. Peaks measured per pixel (1000² and 2000² images, forty-third session):
    // slab 71 B on 1 rank, 43 (rank 0) and 30 B (rank 1) on 2; sphere_ground 105, 71 and 35 B.
    // A flat 40 B had rank 0 of a 2400² slab image at 0.56 of its peak.
    const bool ground = s.background.kind == BackgroundSpec::Kind::ground;
    // Whole bytes, so that the estimate stays an integer (its parts then cancel exactly).
    const double pixel_bytes = 40.0 + std::ceil((ground ? 70.0 : 35.0) / d.size());
    const double image = pixel_bytes * s.camera.width * s.camera.height;
    MemoryEstimate m{40.0 * 1024 * 1024 + local_cells * 8 * fields + image, "light pass, render"};
    m.image_bytes = image;
    m.image_width = s.camera.width;
    m.image_height = s.camera.height;
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
    // When the image is most of it, more ranks on the node hold more copies of rank 0's share: the
    // grid is not what to shrink (a QA finding: a 16384² image on an 8³ grid blamed the grid).
    const bool image_most = m.image_bytes > 0.5 * m.bytes;
    const std::string advice =
        image_most ? fmt::format("the image ({}x{} pixels, camera.resolution) is {:.1f} GiB of it on every rank: use a "
                                 "smaller camera.resolution, or fewer ranks per node",
                                 m.image_width, m.image_height, m.image_bytes / kGiB)
        : m.replicated ? "Monte Carlo copies the grid to every rank: run fewer ranks per node (more nodes), or a "
                         "coarser grid"
                       : "use more ranks (on more nodes) or a smaller grid";
    check_collective(comm, avail <= 0 || node_bytes <= avail,
                     fmt::format("the {} does not fit in memory: a run needs about {:.1f} GiB per rank ({}), "
                                 "{:.1f} GiB for the {} rank(s) on this node, which has {:.1f} GiB available; {}",
                                 image_most ? "run" : "grid", m.bytes / kGiB, m.what, node_bytes / kGiB, ranks_on_node,
                                 avail / kGiB, advice));
}

}  // namespace nimbus::cmd
