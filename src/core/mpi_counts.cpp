#include "src/core/mpi_counts.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>

#include "src/core/error.h"

namespace nimbus {

BlockCounts::BlockCounts(MPI_Comm comm, const std::vector<std::int64_t>& counts, const std::vector<std::int64_t>& displs,
                         MPI_Datatype element, const std::vector<std::int64_t>& also, std::int64_t limit) {
    std::int64_t g = 0, largest = 0;
    for (const std::vector<std::int64_t>* v : {&counts, &displs, &also})
        for (std::int64_t x : *v) {
            g = std::gcd(g, x);
            largest = std::max(largest, x);
        }
    block_ = g > 0 ? g : 1;
    // The smallest block that keeps every count within the limit: g itself, if any does.
    const bool fits = largest / block_ <= limit;
    check_collective(comm, fits,
                     fmt::format("a collective of {} elements does not fit MPI's int counts even in blocks of {} "
                                 "(the greatest common divisor of the counts); use more ranks",
                                 largest, block_));
    if (block_ > 1 && largest > limit) {
        MPI_Type_contiguous(static_cast<int>(block_), element, &type_);
        MPI_Type_commit(&type_);
        owned_ = true;
    } else {
        block_ = 1;  // everything fits as elements: no derived type
        type_ = element;
    }
    for (std::int64_t c : counts) counts_.push_back(static_cast<int>(c / block_));
    for (std::int64_t d : displs) displs_.push_back(static_cast<int>(d / block_));
}

BlockCounts::~BlockCounts() {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (owned_ && !finalized) MPI_Type_free(&type_);
}

std::vector<double> reduce_scatter_sum(MPI_Comm comm, const std::vector<double>& send,
                                       const std::vector<std::int64_t>& recv_counts, std::int64_t limit) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    std::vector<double> recv(static_cast<size_t>(recv_counts[static_cast<size_t>(rank)]));
    const bool fits = std::all_of(recv_counts.begin(), recv_counts.end(), [&](std::int64_t c) { return c <= limit; });
    if (fits) {
        std::vector<int> counts(recv_counts.begin(), recv_counts.end());
        MPI_Reduce_scatter(send.data(), recv.data(), counts.data(), MPI_DOUBLE, MPI_SUM, comm);
        return recv;
    }
    std::int64_t offset = 0;
    for (size_t r = 0; r < recv_counts.size(); ++r) {
        for (std::int64_t done = 0; done < recv_counts[r];) {
            const std::int64_t piece = std::min(limit, recv_counts[r] - done);
            MPI_Reduce(send.data() + offset + done, static_cast<int>(r) == rank ? recv.data() + done : nullptr,
                       static_cast<int>(piece), MPI_DOUBLE, MPI_SUM, static_cast<int>(r), comm);
            done += piece;
        }
        offset += recv_counts[r];
    }
    return recv;
}

}  // namespace nimbus
