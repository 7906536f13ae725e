// MPI calls on more than 2^31 - 1 elements. MPI-3's counts and displacements are int; a grid
// of 2048 x 1024 x 1024 cells, or a PSF light volume with 9 components per cell at 1024³, exceeds
// that. The ways round it:
//   BlockCounts (v-collectives that move whole grids): counts and displacements in blocks of b
//     elements, b a divisor of their greatest common divisor g (a slab's layer, typically), with
//     a contiguous datatype of b elements. The partner's block may differ: MPI matches type
//     signatures element by element.
//   LargeCount (one message, or one file read): n elements as one element of a derived type of
//     exactly n elements, which any n allows.
//   reduce_scatter_sum: MPI_Reduce_scatter when every count fits, else one MPI_Reduce per
//     destination rank in pieces that fit.
// In every case a call whose counts fit is the plain call on the element type: no derived type.
// `limit` (the largest count MPI takes) is a parameter only so that the tests can exercise the
// large-count paths with small arrays.
#pragma once

#include <mpi.h>

#include <climits>
#include <cstdint>
#include <span>
#include <vector>

namespace nimbus {

// The block BlockCounts moves its values in, given their greatest common divisor `gcd` and the
// largest of them: 1 when `largest` fits in `limit`; else the largest divisor of gcd within
// `limit` (the block's own length is an int too), which leaves the fewest blocks; 0 when even
// that leaves largest / block above `limit` (then no divisor does). Pure arithmetic.
std::int64_t choose_block(std::int64_t gcd, std::int64_t largest, std::int64_t limit = INT_MAX);

class BlockCounts {
public:
    // Collective over comm (the element counts may differ by rank; whether they fit is agreed):
    // throws Error on every rank when no block (choose_block) makes them fit in `limit`. `also`
    // lists further counts that must be whole blocks (the send count of an Allgatherv).
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

// n contiguous elements as the (count, datatype) pair MPI takes: (n, element) when n fits in
// `limit`; else (1, a derived type of exactly n elements: n / limit chunks of `limit` elements,
// then the rest; BigMPI's MPIX_Type_contiguous_x). Only the number of elements has to agree
// between a message's sender and receiver. A request still pending when this object goes keeps
// working (freeing a type leaves pending communication alone). Not collective.
class LargeCount {
public:
    LargeCount(std::int64_t n, MPI_Datatype element, std::int64_t limit = INT_MAX);
    ~LargeCount();
    LargeCount(const LargeCount&) = delete;
    LargeCount& operator=(const LargeCount&) = delete;

    int count() const { return count_; }
    MPI_Datatype type() const { return type_; }

private:
    int count_ = 0;
    MPI_Datatype type_ = MPI_DATATYPE_NULL;
    bool owned_ = false;
};

// MPI_Isend, MPI_Irecv, MPI_Recv and MPI_Sendrecv (one tag) of buf.size() doubles, any size
// (LargeCount). The buffers are the caller's and must outlive the requests.
void isend_doubles(std::span<const double> buf, int dest, int tag, MPI_Comm comm, MPI_Request* req);
void irecv_doubles(std::span<double> buf, int source, int tag, MPI_Comm comm, MPI_Request* req);
void recv_doubles(std::span<double> buf, int source, int tag, MPI_Comm comm);
void sendrecv_doubles(std::span<const double> send, int dest, std::span<double> recv, int source, int tag,
                      MPI_Comm comm);

// MPI_Allgatherv of doubles with 64-bit counts (BlockCounts): rank r's counts[r] values `mine`
// land at displs[r] of `all` on every rank. Collective; counts and displs are the same on every
// rank, mine.size() is this rank's count.
void allgatherv_doubles(MPI_Comm comm, std::span<const double> mine, double* all,
                        const std::vector<std::int64_t>& counts, const std::vector<std::int64_t>& displs);

// Sums `send` (the ranks' contributions, recv_counts[r] values for rank r, in rank order) over
// the ranks; returns this rank's recv_counts[rank] sums. Collective; recv_counts is the same on
// every rank.
std::vector<double> reduce_scatter_sum(MPI_Comm comm, const std::vector<double>& send,
                                       const std::vector<std::int64_t>& recv_counts, std::int64_t limit = INT_MAX);

}  // namespace nimbus
