#include "src/core/mpi_counts.h"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>

#include "src/core/error.h"

namespace nimbus {

namespace {

// Frees a type this code committed (not after MPI_Finalize: a static's destructor may run then).
void free_type(MPI_Datatype& type) {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) MPI_Type_free(&type);
}

}  // namespace

std::int64_t choose_block(std::int64_t gcd, std::int64_t largest, std::int64_t limit) {
    if (largest <= limit) return 1;
    // Divisors in pairs (d, gcd / d), d up to sqrt(gcd): the large ones shrink as d grows, so the
    // first that fits is the largest; else the largest small one within the limit.
    std::int64_t block = 1;
    for (std::int64_t d = 1; d <= gcd / d; ++d) {
        if (gcd % d != 0) continue;
        if (gcd / d <= limit) {
            block = gcd / d;
            break;
        }
        if (d <= limit) block = d;
    }
    return largest / block <= limit ? block : 0;
}

BlockCounts::BlockCounts(MPI_Comm comm, const std::vector<std::int64_t>& counts, const std::vector<std::int64_t>& displs,
                         MPI_Datatype element, const std::vector<std::int64_t>& also, std::int64_t limit) {
    std::int64_t g = 0, largest = 0;
    for (const std::vector<std::int64_t>* v : {&counts, &displs, &also})
        for (std::int64_t x : *v) {
            g = std::gcd(g, x);
            largest = std::max(largest, x);
        }
    block_ = choose_block(g, largest, limit);
    check_collective(comm, block_ > 0,
                     fmt::format("a collective of {} elements does not fit MPI's int counts even in blocks (a "
                                 "divisor of {}, the greatest common divisor of the counts); use more ranks",
                                 largest, g));
    if (block_ > 1) {
        MPI_Type_contiguous(static_cast<int>(block_), element, &type_);
        MPI_Type_commit(&type_);
        owned_ = true;
    } else {
        type_ = element;  // everything fits as elements: no derived type
    }
    for (std::int64_t c : counts) counts_.push_back(static_cast<int>(c / block_));
    for (std::int64_t d : displs) displs_.push_back(static_cast<int>(d / block_));
}

BlockCounts::~BlockCounts() {
    if (owned_) free_type(type_);
}

LargeCount::LargeCount(std::int64_t n, MPI_Datatype element, std::int64_t limit) {
    if (n <= limit) {
        count_ = static_cast<int>(n);
        type_ = element;
        return;
    }
    const std::int64_t chunks = n / limit, rest = n % limit;
    MPI_Datatype chunk = MPI_DATATYPE_NULL, body = MPI_DATATYPE_NULL;
    MPI_Type_contiguous(static_cast<int>(limit), element, &chunk);
    MPI_Type_contiguous(static_cast<int>(chunks), chunk, &body);
    MPI_Type_free(&chunk);  // a derived type keeps what it is built from
    if (rest == 0) {
        type_ = body;
    } else {
        MPI_Datatype tail = MPI_DATATYPE_NULL;
        MPI_Type_contiguous(static_cast<int>(rest), element, &tail);
        MPI_Aint lb = 0, extent = 0;
        MPI_Type_get_extent(element, &lb, &extent);
        int lengths[2] = {1, 1};
        MPI_Aint at[2] = {0, static_cast<MPI_Aint>(chunks * limit) * extent};
        MPI_Datatype parts[2] = {body, tail};
        MPI_Type_create_struct(2, lengths, at, parts, &type_);
        MPI_Type_free(&body);
        MPI_Type_free(&tail);
    }
    MPI_Type_commit(&type_);
    count_ = 1;
    owned_ = true;
}

LargeCount::~LargeCount() {
    if (owned_) free_type(type_);
}

void isend_doubles(std::span<const double> buf, int dest, int tag, MPI_Comm comm, MPI_Request* req) {
    const LargeCount n(static_cast<std::int64_t>(buf.size()), MPI_DOUBLE);
    MPI_Isend(buf.data(), n.count(), n.type(), dest, tag, comm, req);
}

void irecv_doubles(std::span<double> buf, int source, int tag, MPI_Comm comm, MPI_Request* req) {
    const LargeCount n(static_cast<std::int64_t>(buf.size()), MPI_DOUBLE);
    MPI_Irecv(buf.data(), n.count(), n.type(), source, tag, comm, req);
}

void recv_doubles(std::span<double> buf, int source, int tag, MPI_Comm comm) {
    const LargeCount n(static_cast<std::int64_t>(buf.size()), MPI_DOUBLE);
    MPI_Recv(buf.data(), n.count(), n.type(), source, tag, comm, MPI_STATUS_IGNORE);
}

void sendrecv_doubles(std::span<const double> send, int dest, std::span<double> recv, int source, int tag,
                      MPI_Comm comm) {
    const LargeCount ns(static_cast<std::int64_t>(send.size()), MPI_DOUBLE),
        nr(static_cast<std::int64_t>(recv.size()), MPI_DOUBLE);
    MPI_Sendrecv(send.data(), ns.count(), ns.type(), dest, tag, recv.data(), nr.count(), nr.type(), source, tag,
                 comm, MPI_STATUS_IGNORE);
}

void allgatherv_doubles(MPI_Comm comm, std::span<const double> mine, double* all,
                        const std::vector<std::int64_t>& counts, const std::vector<std::int64_t>& displs) {
    const auto n = static_cast<std::int64_t>(mine.size());
    const BlockCounts bc(comm, counts, displs, MPI_DOUBLE, {n});
    MPI_Allgatherv(mine.data(), bc.blocks(n), bc.type(), all, bc.counts(), bc.displs(), bc.type(), comm);
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
