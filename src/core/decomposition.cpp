#include "src/core/decomposition.h"

#include <fmt/format.h>

#include <algorithm>

#include "src/core/error.h"

namespace nimbus {

// The process grid for nranks: proc_dims with its 0 entries filled (all zeros: slabs along z),
// checked against the rank count and the grid. planned: nranks is `info --ranks`, not mpiexec.
Int3 Decomposition::choose_dims(const Int3& n, int nranks, Int3 proc_dims, bool planned) {
    if (n[0] <= 0 || n[1] <= 0 || n[2] <= 0)
        throw Error(fmt::format("grid has zero size ({} x {} x {} cells)", n[0], n[1], n[2]));
    if (nranks < 1) throw Error(fmt::format("a run needs at least 1 rank, not {}", nranks));
    if (proc_dims == Int3{0, 0, 0}) proc_dims = {1, 1, 0};
    int fixed = 1, free_axes = 0;
    for (int d = 0; d < 3; ++d) {
        if (proc_dims[d] < 0) throw Error("process grid entries must be >= 0");
        if (proc_dims[d] > 0) fixed *= proc_dims[d]; else ++free_axes;
    }
    if (free_axes > 0) {
        if (nranks % fixed != 0)
            throw Error(fmt::format("process grid [{}, {}, {}]: the fixed entries (product {}) do not divide the {} "
                                    "ranks (0 = chosen to fit)",
                                    proc_dims[0], proc_dims[1], proc_dims[2], fixed, nranks));
        MPI_Dims_create(nranks, 3, proc_dims.data());  // local: no communication
    }
    const int needed = proc_dims[0] * proc_dims[1] * proc_dims[2];
    if (needed != nranks)
        throw Error(planned ? fmt::format("process grid {}x{}x{} needs {} ranks, not the {} of --ranks",
                                          proc_dims[0], proc_dims[1], proc_dims[2], needed, nranks)
                            : fmt::format("process grid {}x{}x{} needs {} ranks, but {} {} started (mpiexec -n {})",
                                          proc_dims[0], proc_dims[1], proc_dims[2], needed, nranks,
                                          nranks == 1 ? "was" : "were", needed));
    for (int d = 0; d < 3; ++d)
        if (proc_dims[d] > n[d])
            throw Error(fmt::format(
                "{} ranks along {} but the grid has only {} cell{} there: some ranks would own "
                "no cells; run with at most {} rank{} or change the process grid",
                proc_dims[d], "xyz"[d], n[d], n[d] == 1 ? "" : "s", nranks / proc_dims[d] * n[d],
                nranks / proc_dims[d] * n[d] == 1 ? "" : "s"));
    return proc_dims;
}

Decomposition::Decomposition(MPI_Comm comm, const Int3& n, Int3 proc_dims,
                             std::array<bool, 3> periodic)
    : global_{{0, 0, 0}, n}, periodic_(periodic) {
    int nranks = 1;
    MPI_Comm_size(comm, &nranks);
    dims_ = choose_dims(n, nranks, proc_dims, false);

    int periods[3] = {periodic[0], periodic[1], periodic[2]};
    MPI_Comm cart = MPI_COMM_NULL;
    MPI_Cart_create(comm, 3, dims_.data(), periods, /*reorder=*/0, &cart);
    comm_ = std::shared_ptr<MPI_Comm>(new MPI_Comm(cart), [](MPI_Comm* c) {
        int finalized = 0;
        MPI_Finalized(&finalized);
        if (!finalized && *c != MPI_COMM_NULL) MPI_Comm_free(c);
        delete c;
    });
    MPI_Comm_rank(cart, &rank_);
    MPI_Comm_size(cart, &size_);
    MPI_Cart_coords(cart, rank_, 3, coords_.data());
    local_ = box_of(rank_);
}

Decomposition Decomposition::plan(const Int3& n, int nranks, Int3 proc_dims, std::array<bool, 3> periodic,
                                  int as_rank) {
    Decomposition out;
    out.global_ = {{0, 0, 0}, n};
    out.periodic_ = periodic;
    out.dims_ = choose_dims(n, nranks, proc_dims, true);
    if (as_rank < 0 || as_rank >= nranks) throw Error(fmt::format("rank {} is not one of {} ranks", as_rank, nranks));
    out.comm_ = std::make_shared<MPI_Comm>(MPI_COMM_NULL);
    out.rank_ = as_rank;
    out.size_ = nranks;
    out.coords_ = out.coords_of(as_rank);
    out.local_ = out.box_of(as_rank);
    return out;
}

// MPI numbers the ranks of a Cartesian grid in row-major order (z fastest), and the grid is
// created without reordering, so the coordinates follow from the rank alone.
Int3 Decomposition::coords_of(int r) const {
    return {r / (dims_[1] * dims_[2]), r / dims_[2] % dims_[1], r % dims_[2]};
}

Box Decomposition::box_of(int r) const {
    const Int3 c = coords_of(r);
    Box b;
    for (int d = 0; d < 3; ++d) {
        b.lo[d] = split_lo(global_.hi[d], dims_[d], c[d]);
        b.hi[d] = split_lo(global_.hi[d], dims_[d], c[d] + 1);
    }
    return b;
}

std::vector<int> Decomposition::cuts(int axis) const {
    std::vector<int> out;
    for (int p = 0; p <= dims_[axis]; ++p) out.push_back(split_lo(global_.hi[axis], dims_[axis], p));
    return out;
}

int Decomposition::thinnest(int axis) const {
    const std::vector<int> c = cuts(axis);
    int thin = global_.hi[axis] - global_.lo[axis];
    for (size_t p = 0; p + 1 < c.size(); ++p) thin = std::min(thin, c[p + 1] - c[p]);
    return thin;
}

int Decomposition::neighbor(int axis, int dir) const {
    int src = MPI_PROC_NULL, dst = MPI_PROC_NULL;
    MPI_Cart_shift(*comm_, axis, dir, &src, &dst);
    return dst;
}

std::string Decomposition::describe() const {
    return fmt::format("{} rank{} as {}x{}x{}{}", size_, size_ == 1 ? "" : "s", dims_[0], dims_[1],
                       dims_[2], is_slab_z() ? " (slabs along z)" : "");
}

void Decomposition::require_z_slabs(const std::string& who, const std::string& why) const {
    if (!is_slab_z())
        throw Error(fmt::format("{} needs slabs along z (grid.process_grid = [1, 1, P]): {}; got {}", who, why,
                                describe()));
    if (periodic(2))
        throw Error(fmt::format("{}: grid.periodic z is not supported ({}); use periodic x/y only", who, why));
}

}  // namespace nimbus
