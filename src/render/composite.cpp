#include "src/render/composite.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <cstring>

#include "src/core/error.h"

namespace nimbus {

void FragmentBuffer::push_floats(const double* v) {
    for (int b = 0; b < nbands_; ++b) words_.push_back(std::bit_cast<std::uint32_t>(static_cast<float>(v[b])));
}

void FragmentBuffer::pad_held() {
    if (held_) words_.insert(words_.end(), static_cast<size_t>(3 * nbands_ + 1), 0u);
}

void FragmentBuffer::add_segment(std::int32_t pixel, std::int32_t key, const double* C, const double* T) {
    words_.push_back(static_cast<std::uint32_t>(pixel));
    words_.push_back(static_cast<std::uint32_t>(key));
    push_floats(C);
    push_floats(T);
    pad_held();
}

void FragmentBuffer::add_segment_held(std::int32_t pixel, std::int32_t key, const double* C,
                                      const double* T, const double* A, const double* H_spec,
                                      const double* H_last, bool has_spec, bool has_sample) {
    if (!held_) throw Error("render: FragmentBuffer without held source terms");
    words_.push_back(static_cast<std::uint32_t>(pixel));
    words_.push_back(static_cast<std::uint32_t>(key));
    push_floats(C);
    push_floats(T);
    push_floats(A);
    push_floats(H_spec);
    push_floats(H_last);
    words_.push_back((has_spec ? 1u : 0u) | (has_sample ? 2u : 0u));
}

void FragmentBuffer::add_background(std::int32_t pixel, const double* L) {
    words_.push_back(static_cast<std::uint32_t>(pixel));
    words_.push_back(static_cast<std::uint32_t>(kBackgroundKey));
    for (int b = 0; b < nbands_; ++b) words_.push_back(std::bit_cast<std::uint32_t>(static_cast<float>(L[b])));
    for (int b = 0; b < nbands_; ++b) words_.push_back(std::bit_cast<std::uint32_t>(0.0f));
    pad_held();
}

namespace {

int row_begin(int height, int nranks, int r) {
    return static_cast<int>(static_cast<long long>(height) * r / nranks);
}

// Sends every record to the owner of its row; returns the records this rank owns.
std::vector<std::uint32_t> exchange_fragments(const FragmentBuffer& local, int width,
                                              const std::vector<int>& row_owner, int nranks,
                                              MPI_Comm comm) {
    const int rw = local.record_words();
    const std::vector<std::uint32_t>& words = local.words();
    const size_t nrec = local.size();
    std::vector<int> dest(nrec);
    std::vector<long long> count(static_cast<size_t>(nranks), 0);
    for (size_t r = 0; r < nrec; ++r) {
        const auto pixel = static_cast<std::int32_t>(words[r * rw]);
        dest[r] = row_owner[static_cast<size_t>(pixel / width)];
        ++count[static_cast<size_t>(dest[r])];
    }
    static const char* kTooMany = "render: too many image fragments for one MPI message; use a smaller image";
    std::vector<int> send_counts(static_cast<size_t>(nranks)), send_displs(static_cast<size_t>(nranks));
    check_collective(comm, static_cast<long long>(nrec) <= INT_MAX, kTooMany);
    long long offset = 0;
    for (int p = 0; p < nranks; ++p) {
        send_displs[static_cast<size_t>(p)] = static_cast<int>(offset);
        send_counts[static_cast<size_t>(p)] = static_cast<int>(count[static_cast<size_t>(p)]);
        offset += count[static_cast<size_t>(p)];
    }
    std::vector<std::uint32_t> send(words.size());
    std::vector<long long> fill(send_displs.begin(), send_displs.end());
    for (size_t r = 0; r < nrec; ++r) {
        const long long at = fill[static_cast<size_t>(dest[r])]++;
        std::memcpy(&send[static_cast<size_t>(at) * rw], &words[r * rw], sizeof(std::uint32_t) * rw);
    }
    std::vector<int> recv_counts(static_cast<size_t>(nranks)), recv_displs(static_cast<size_t>(nranks));
    MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm);
    long long total = 0;
    for (int p = 0; p < nranks; ++p) {
        recv_displs[static_cast<size_t>(p)] = static_cast<int>(std::min<long long>(total, INT_MAX));
        total += recv_counts[static_cast<size_t>(p)];
    }
    check_collective(comm, total <= INT_MAX, kTooMany);
    std::vector<std::uint32_t> recv(static_cast<size_t>(total) * rw);
    MPI_Datatype record;
    MPI_Type_contiguous(rw, MPI_UINT32_T, &record);
    MPI_Type_commit(&record);
    MPI_Alltoallv(send.data(), send_counts.data(), send_displs.data(), record, recv.data(),
                  recv_counts.data(), recv_displs.data(), record, comm);
    MPI_Type_free(&record);
    return recv;
}

}  // namespace

Image composite_image(const FragmentBuffer& local, int width, int height,
                      const std::vector<double>& sky, MPI_Comm comm) {
    int rank = 0, nranks = 1;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &nranks);
    const int nb = local.nbands(), rw = local.record_words();
    if (nb != 1 && nb != 3) throw Error("render: the image needs 1 (gray) or 3 (rgb) bands");

    std::vector<int> row_owner(static_cast<size_t>(height));
    for (int p = 0; p < nranks; ++p)
        for (int y = row_begin(height, nranks, p); y < row_begin(height, nranks, p + 1); ++y)
            row_owner[static_cast<size_t>(y)] = p;
    const std::vector<std::uint32_t> recv = exchange_fragments(local, width, row_owner, nranks, comm);

    // Bucket the received records by local pixel (counting sort), then composite each pixel.
    const int y0 = row_begin(height, nranks, rank), y1 = row_begin(height, nranks, rank + 1);
    const size_t npix = static_cast<size_t>(y1 - y0) * width, nrec = recv.size() / rw;
    const size_t first_pixel = static_cast<size_t>(y0) * width;
    std::vector<size_t> start(npix + 1, 0), order(nrec);
    for (size_t r = 0; r < nrec; ++r) ++start[recv[r * rw] - first_pixel + 1];
    for (size_t p = 0; p < npix; ++p) start[p + 1] += start[p];
    {
        std::vector<size_t> fill(start.begin(), start.end() - 1);
        for (size_t r = 0; r < nrec; ++r) order[fill[recv[r * rw] - first_pixel]++] = r;
    }
    auto key = [&](size_t r) { return static_cast<std::int32_t>(recv[r * rw + 1]); };
    // Band values of record r: which = 0 for C (or the ground radiance), 1 for T, and with a
    // held source 2 for A, 3 for H_spec, 4 for H_last.
    auto values = [&](size_t r, int which, float* out) {
        for (int b = 0; b < nb; ++b)
            out[b] = std::bit_cast<float>(recv[r * rw + 2 + static_cast<size_t>(which * nb + b)]);
    };

    const bool held = local.held_source();
    auto flags = [&](size_t r) { return recv[r * rw + 2 + static_cast<size_t>(5 * nb)]; };
    std::vector<float> rows(npix * 4);
    double C[3], T[3], H[3];
    for (size_t p = 0; p < npix; ++p) {
        std::sort(order.begin() + static_cast<std::ptrdiff_t>(start[p]),
                  order.begin() + static_cast<std::ptrdiff_t>(start[p + 1]),
                  [&](size_t a, size_t b) { return key(a) < key(b); });
        for (int b = 0; b < nb; ++b) { C[b] = 0.0; T[b] = 1.0; H[b] = 0.0; }
        bool ground = false, H_set = false;
        double T_volume[3];
        for (size_t q = start[p]; q < start[p + 1]; ++q) {
            const size_t r = order[q];
            float c[3], t[3];
            values(r, 0, c);
            if (key(r) == FragmentBuffer::kBackgroundKey) {
                std::copy(T, T + nb, T_volume);
                for (int b = 0; b < nb; ++b) C[b] += T[b] * c[b];
                ground = true;
                break;
            }
            values(r, 1, t);
            if (held) {
                float a[3], hs[3], hl[3];
                values(r, 2, a);
                values(r, 3, hs);
                values(r, 4, hl);
                const bool has_spec = (flags(r) & 1u) != 0, has_sample = (flags(r) & 2u) != 0;
                for (int b = 0; b < nb; ++b) {
                    const double h_use = H_set ? H[b] : (has_spec ? hs[b] : 0.0);
                    C[b] += T[b] * a[b] * h_use;
                    H[b] = has_sample ? hl[b] : h_use;
                }
                H_set = H_set || has_spec || has_sample;
            }
            composite_over(nb, C, T, c, t);
        }
        if (!ground) {
            std::copy(T, T + nb, T_volume);
            for (int b = 0; b < nb; ++b) C[b] += T[b] * sky[static_cast<size_t>(b)];
        }
        float* out = &rows[p * 4];
        double mean_T = 0.0;
        for (int b = 0; b < nb; ++b) mean_T += T_volume[b];
        for (int c = 0; c < 3; ++c) out[c] = static_cast<float>(C[nb == 1 ? 0 : c]);
        out[3] = static_cast<float>(1.0 - mean_T / nb);
    }

    // Rank 0 gathers the rows in rank order, which is top-to-bottom row order.
    std::vector<int> counts(static_cast<size_t>(nranks)), displs(static_cast<size_t>(nranks));
    for (int p = 0; p < nranks; ++p) {
        displs[static_cast<size_t>(p)] = row_begin(height, nranks, p) * width * 4;
        counts[static_cast<size_t>(p)] = (row_begin(height, nranks, p + 1) - row_begin(height, nranks, p)) * width * 4;
    }
    Image image;
    if (rank == 0) image = Image(width, height);
    MPI_Gatherv(rows.data(), static_cast<int>(rows.size()), MPI_FLOAT,
                rank == 0 ? image.rgba.data() : nullptr, counts.data(), displs.data(), MPI_FLOAT, 0, comm);
    return image;
}

}  // namespace nimbus
