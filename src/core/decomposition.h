// Decomposition: the global grid split over an MPI Cartesian process grid, one box per rank.
// Default: slabs along z (process grid 1 x 1 x P), the layout the sweeps pipeline over.
// Owns its Cartesian communicator. Knows nothing about any solver.
#pragma once

#include <mpi.h>

#include <memory>
#include <string>
#include <vector>

#include "src/core/box.h"

namespace nimbus {

class Decomposition {
public:
    // Collective over `comm`. proc_dims: ranks per axis; 0 entries are filled so that the
    // product is the rank count (all zeros -> slabs along z). Throws Error on every rank when
    // a rank would own no cells or the dims do not multiply to the rank count.
    Decomposition(MPI_Comm comm, const Int3& global_cells, Int3 proc_dims = {0, 0, 0},
                  std::array<bool, 3> periodic = {false, false, false});

    // The decomposition nranks ranks would have, seen from rank as_rank, without MPI ranks or
    // communication (`nimbus info --ranks N` plans a run with it): the same process grid and
    // boxes as the constructor's, and the same errors; comm() is MPI_COMM_NULL, so neighbor()
    // and anything collective must not be used on it.
    static Decomposition plan(const Int3& global_cells, int nranks, Int3 proc_dims = {0, 0, 0},
                              std::array<bool, 3> periodic = {false, false, false}, int as_rank = 0);

    MPI_Comm comm() const { return *comm_; }
    int rank() const { return rank_; }
    int size() const { return size_; }
    const Box& global() const { return global_; }
    const Box& local() const { return local_; }
    const Int3& dims() const { return dims_; }
    const Int3& coords() const { return coords_; }
    bool periodic(int axis) const { return periodic_[axis]; }
    bool is_slab_z() const { return dims_[0] == 1 && dims_[1] == 1; }
    // For a method that works on the z slabs: throws Error (the same on every rank) unless the
    // grid is split along z only and z is not periodic. who: "model lpm"; why: what needs it.
    void require_z_slabs(const std::string& who, const std::string& why) const;

    // Rank of the neighbour one step along `axis` in direction dir (+1/-1); MPI_PROC_NULL at a
    // non-periodic domain boundary.
    int neighbor(int axis, int dir) const;
    // The box owned by any rank (computable locally, no communication).
    Box box_of(int rank) const;
    // Whether this rank's box touches the low/high domain face along axis.
    bool at_low_boundary(int axis) const { return local_.lo[axis] == global_.lo[axis]; }
    bool at_high_boundary(int axis) const { return local_.hi[axis] == global_.hi[axis]; }

    std::string describe() const;  // e.g. "2 ranks as 1x1x2 (slabs along z)"

    // Where the cells along `axis` are split: dims()[axis] + 1 values from low to high face.
    std::vector<int> cuts(int axis) const;

    // First cell of part p when n cells are split into `parts` nearly equal parts (the split of
    // every axis; parts differ by at most one cell).
    static int split_lo(int n, int parts, int p) { return static_cast<int>((long long)n * p / parts); }
    // Cells along `axis` of the thinnest rank box.
    int thinnest(int axis) const;

private:
    Decomposition() = default;
    static Int3 choose_dims(const Int3& n, int nranks, Int3 proc_dims, bool planned);
    Int3 coords_of(int rank) const;

    std::shared_ptr<MPI_Comm> comm_;
    int rank_ = 0, size_ = 1;
    Box global_{}, local_{};
    Int3 dims_{1, 1, 1}, coords_{0, 0, 0};
    std::array<bool, 3> periodic_{false, false, false};
};

}  // namespace nimbus
