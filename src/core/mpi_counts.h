// MPI collectives on more than 2^31 - 1 elements. MPI-3's counts and displacements are int;
// a grid of 2048 x 1024 x 1024 cells, or a PSF light volume with 9 components per cell at 1024³,
// exceeds that. Two ways round it, used by the v-collectives that move whole grids:
//   BlockCounts: counts and displacements in blocks of g elements, g the greatest common divisor
//     of them all (a slab's layer, typically), with a contiguous datatype of g elements. The
//     partner's block may differ: MPI matches type signatures element by element.
//   reduce_scatter_sum: MPI_Reduce_scatter when every count fits, else one MPI_Reduce per
//     destination rank in pieces that fit.
// `limit` (the largest count MPI takes) is a parameter only so that the tests can exercise the
// large-count paths with small arrays.
#pragma once

#include <mpi.h>

#include <climits>
#include <cstdint>
#include <vector>

namespace nimbus {

class BlockCounts {
public:
    // Collective over comm (the element counts may differ by rank; whether they fit is agreed):
    // throws Error on every rank when even in blocks a count does not fit in `limit`. `also` lists
    // further counts that must be whole blocks (the send count of an Allgatherv).
    BlockCounts(MPI_Comm comm, const std::vector<std::int64_t>& counts, const std::vector<std::int64_t>& displs,
                MPI_Datatype element, const std::vector<std::int64_t>& also = {}, std::int64_t limit = INT_MAX);
    ~BlockCounts();
    BlockCounts(const BlockCounts&) = delete;
    BlockCounts& operator=(const BlockCounts&) = delete;

    MPI_Datatype type() const { return type_; }
    std::int64_t block() const { return block_; }
    const int* counts() const { return counts_.data(); }
    const int* displs() const { return displs_.data(); }
    int blocks(std::int64_t elements) const { return static_cast<int>(elements / block_); }

private:
    MPI_Datatype type_ = MPI_DATATYPE_NULL;
    bool owned_ = false;
    std::int64_t block_ = 1;
    std::vector<int> counts_, displs_;
};

// Sums `send` (the ranks' contributions, recv_counts[r] values for rank r, in rank order) over
// the ranks; returns this rank's recv_counts[rank] sums. Collective; recv_counts is the same on
// every rank.
std::vector<double> reduce_scatter_sum(MPI_Comm comm, const std::vector<double>& send,
                                       const std::vector<std::int64_t>& recv_counts, std::int64_t limit = INT_MAX);

}  // namespace nimbus
