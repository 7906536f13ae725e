// A sequence of groups passed down the z-slab chain: the pipelined pass of the LPM z maps (one
// group of directions at a time) and of the exact light pass (one rank's rays at a time). For
// each group g in order, a rank receives the upstream rank's message of g, runs the caller's
// step, and sends the step's output downstream without blocking, so the downstream rank starts
// on group g while this one works on g + 1 (KBA pipelining over groups instead of tiles).
//
// The chain is this rank's column of the process grid along z, in direction dir: +1 data moves
// toward increasing z, -1 toward decreasing z, 0 no chain (every rank alone: no messages).
// Position 0 is the head (no upstream rank). A periodic z is not wrapped (as in sweep::run).
#pragma once

#include <mpi.h>

#include <deque>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/mpi_counts.h"

namespace nimbus::sweep {

// This rank's place in the chain of direction dir. Not collective.
struct ChainLink {
    int up = MPI_PROC_NULL;    // upstream neighbour (MPI_PROC_NULL at the head)
    int down = MPI_PROC_NULL;  // downstream neighbour (MPI_PROC_NULL at the end)
    int position = 0;          // 0 at the head
    int length = 1;            // ranks in the chain
};

inline ChainLink chain_link(const Decomposition& d, int dir) {
    ChainLink l;
    if (dir == 0) return l;
    const int z = d.coords()[2], nz = d.dims()[2];
    l.length = nz;
    l.position = dir > 0 ? z : nz - 1 - z;
    if (l.position > 0) l.up = d.neighbor(2, -dir);
    if (l.position < nz - 1) l.down = d.neighbor(2, dir);
    return l;
}

// The rank at chain position `position` in this rank's z column. Not collective.
inline int chain_rank(const Decomposition& d, int dir, int position) {
    if (dir == 0) return d.rank();
    int coords[3] = {d.coords()[0], d.coords()[1], dir > 0 ? position : d.dims()[2] - 1 - position};
    int r = 0;
    MPI_Cart_rank(d.comm(), coords, &r);
    return r;
}

struct ChainStats {
    double wait_seconds = 0;  // blocked on upstream messages and on downstream sends (capacity, the last ones' completion)
    int groups = 0;           // steps this rank ran
};

// The groups a chain carries. Group g's message has size[g] doubles on every link; the group
// starts at the head and stops at chain position last[g] (the rank there keeps the result and
// sends nothing); ranks beyond last[g] do not take part in g. Empty `last`: every group runs the
// whole chain.
struct ChainGroups {
    std::vector<size_t> size;
    std::vector<int> last;
};

// What step(g, io) sees of group g on this rank.
class ChainIO {
public:
    // Upstream's message of g (size[g] doubles); empty at the head. The first call blocks until
    // it has arrived (timed into ChainStats::wait_seconds).
    std::span<const double> in();
    // The message for the downstream rank (size[g] doubles, contents unspecified: the step fills
    // it), sent when step returns; empty where g stops (the chain's end or last[g]).
    std::span<double> out() const { return out_; }

private:
    template <class Step>
    friend ChainStats pass_down(const Decomposition& d, int dir, const ChainGroups& groups,
                                Step&& step);
    MPI_Comm comm_ = MPI_COMM_NULL;
    int up_ = MPI_PROC_NULL, tag_ = 0;
    std::vector<double>* in_ = nullptr;
    bool received_ = false;
    std::span<double> out_;
    double* wait_ = nullptr;
};

// Group g's tag is kChainTagBase + g: clear of the halo exchange (700-722), sweep::run
// (811-813), run_octants (900-923) and the LPM x/y map exchange (950, 951); kChainMaxGroups keeps
// it <= 32767, the smallest MPI_TAG_UB MPI allows. A rank waits for its oldest send before
// starting a new one once kChainSendsInFlight are in flight (memory: that many messages).
constexpr int kChainTagBase = 1000;
constexpr int kChainMaxGroups = 31000;
constexpr int kChainSendsInFlight = 2;

// Collective over this rank's z column of d.comm(): every rank of the chain calls it with the
// same dir and groups. For g = 0, 1, ... that this rank takes part in: step(g, io) (io: ChainIO&)
// runs; its output is sent downstream. Messages of one group have their own tag, so a group
// always meets its own upstream message. Sends are non-blocking from buffers the function owns
// (see kChainSendsInFlight); all have completed when it returns.
template <class Step>
ChainStats pass_down(const Decomposition& d, int dir, const ChainGroups& groups, Step&& step) {
    const int ng = static_cast<int>(groups.size.size());
    if (ng > kChainMaxGroups)
        throw std::invalid_argument("sweep::pass_down: more groups than message tags");
    const ChainLink link = chain_link(d, dir);
    ChainStats stats;
    std::vector<double> in;
    struct Sent {
        MPI_Request req;
        std::vector<double> buf;
    };
    std::deque<Sent> sent;  // in flight, oldest first
    for (int g = 0; g < ng; ++g) {
        const int last =
            groups.last.empty() ? link.length - 1 : groups.last[static_cast<size_t>(g)];
        if (link.position > last) continue;
        const size_t n = groups.size[static_cast<size_t>(g)];
        const bool send = link.position < last && link.down != MPI_PROC_NULL;
        std::vector<double> out;
        if (send && static_cast<int>(sent.size()) == kChainSendsInFlight) {
            const double t0 = MPI_Wtime();
            MPI_Wait(&sent.front().req, MPI_STATUS_IGNORE);
            stats.wait_seconds += MPI_Wtime() - t0;
            out = std::move(sent.front().buf);  // recycled
            sent.pop_front();
        }
        if (send) out.resize(n);
        ChainIO io;
        io.comm_ = d.comm();
        io.up_ = link.up;
        io.tag_ = kChainTagBase + g;
        in.resize(link.up != MPI_PROC_NULL ? n : 0);
        io.in_ = &in;
        io.out_ = std::span<double>(out);
        io.wait_ = &stats.wait_seconds;
        step(g, io);
        io.in();  // the upstream message of g is consumed even if the step did not read it
        ++stats.groups;
        if (send) {
            sent.push_back({MPI_REQUEST_NULL, std::move(out)});
            Sent& s = sent.back();
            isend_doubles(s.buf, link.down, io.tag_, d.comm(), &s.req);
        }
    }
    // The last sends complete when downstream takes them (a large message waits for the
    // matching receive): blocked time, not work.
    const double t0 = MPI_Wtime();
    for (Sent& s : sent) MPI_Wait(&s.req, MPI_STATUS_IGNORE);
    stats.wait_seconds += MPI_Wtime() - t0;
    return stats;
}

inline std::span<const double> ChainIO::in() {
    if (!received_ && up_ != MPI_PROC_NULL) {
        const double t0 = MPI_Wtime();
        recv_doubles(*in_, up_, tag_, comm_);
        *wait_ += MPI_Wtime() - t0;
    }
    received_ = true;
    return *in_;
}

}  // namespace nimbus::sweep
