#include "src/render/view_depth.h"

#include <algorithm>
#include <climits>

#include "src/core/error.h"

namespace nimbus {

std::vector<std::array<double, 2>> view_depth_at_entry(const std::vector<PieceDepth>& pieces,
                                                       int width, int height, MPI_Comm comm) {
    int rank = 0, nranks = 1;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &nranks);
    auto row_begin = [&](int r) { return static_cast<int>(static_cast<long long>(height) * r / nranks); };
    std::vector<int> row_owner(static_cast<size_t>(height));
    for (int p = 0; p < nranks; ++p)
        for (int y = row_begin(p); y < row_begin(p + 1); ++y) row_owner[static_cast<size_t>(y)] = p;

    // 1. Send each piece to its row's owner (counting sort by destination).
    const size_t n = pieces.size();
    std::vector<int> send_counts(static_cast<size_t>(nranks), 0), send_displs(static_cast<size_t>(nranks), 0);
    std::vector<int> dest(n);
    for (size_t i = 0; i < n; ++i) {
        dest[i] = row_owner[static_cast<size_t>(pieces[i].pixel / width)];
        ++send_counts[static_cast<size_t>(dest[i])];
    }
    check_collective(comm, n <= static_cast<size_t>(INT_MAX) / sizeof(PieceDepth),
                     "render: too many view-ray pieces for one MPI message; use a smaller image");
    for (int p = 1; p < nranks; ++p)
        send_displs[static_cast<size_t>(p)] = send_displs[static_cast<size_t>(p - 1)] + send_counts[static_cast<size_t>(p - 1)];
    std::vector<PieceDepth> send(n);
    std::vector<size_t> slot(n);  // send position of piece i
    {
        std::vector<int> fill(send_displs);
        for (size_t i = 0; i < n; ++i) {
            slot[i] = static_cast<size_t>(fill[static_cast<size_t>(dest[i])]++);
            send[slot[i]] = pieces[i];
        }
    }
    std::vector<int> recv_counts(static_cast<size_t>(nranks)), recv_displs(static_cast<size_t>(nranks), 0);
    MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm);
    // What a row owner receives from all ranks must fit MPI's int displacements too (the send
    // side's bound; composite.cpp checks its fragments alike).
    long long total = 0;
    for (int p = 0; p < nranks; ++p) {
        recv_displs[static_cast<size_t>(p)] = static_cast<int>(std::min<long long>(total, INT_MAX));
        total += recv_counts[static_cast<size_t>(p)];
    }
    check_collective(comm, total <= static_cast<long long>(INT_MAX / sizeof(PieceDepth)),
                     "render: too many view-ray pieces for one MPI message; use a smaller image");
    const auto nrecv = static_cast<size_t>(total);
    std::vector<PieceDepth> recv(nrecv);
    MPI_Datatype rec;
    MPI_Type_contiguous(static_cast<int>(sizeof(PieceDepth)), MPI_BYTE, &rec);
    MPI_Type_commit(&rec);
    MPI_Alltoallv(send.data(), send_counts.data(), send_displs.data(), rec, recv.data(),
                  recv_counts.data(), recv_displs.data(), rec, comm);

    // 2. Exclusive prefix per pixel in key order.
    std::vector<size_t> order(nrecv);
    for (size_t i = 0; i < nrecv; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
        return recv[a].pixel != recv[b].pixel ? recv[a].pixel < recv[b].pixel : recv[a].key < recv[b].key;
    });
    std::vector<std::array<double, 2>> reply(nrecv);
    for (size_t q = 0; q < nrecv;) {
        double tau = 0.0, s = 0.0;
        const std::int32_t pixel = recv[order[q]].pixel;
        for (; q < nrecv && recv[order[q]].pixel == pixel; ++q) {
            reply[order[q]] = {tau, s};
            tau += recv[order[q]].tau;
            s += recv[order[q]].s;
        }
    }

    // 3. Return the entry depths to the pieces' ranks (the reverse exchange).
    std::vector<std::array<double, 2>> back(n);
    MPI_Datatype two;
    MPI_Type_contiguous(2, MPI_DOUBLE, &two);
    MPI_Type_commit(&two);
    MPI_Alltoallv(reply.data(), recv_counts.data(), recv_displs.data(), two, back.data(),
                  send_counts.data(), send_displs.data(), two, comm);
    MPI_Type_free(&two);
    MPI_Type_free(&rec);
    std::vector<std::array<double, 2>> out(n);
    for (size_t i = 0; i < n; ++i) out[i] = back[slot[i]];
    return out;
}

}  // namespace nimbus
