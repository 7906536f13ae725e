#include "solvers/psf/pyramid.h"

#include <algorithm>
#include <cmath>

#include "src/core/error.h"
#include "src/core/halo.h"
#include "src/core/mpi_counts.h"

namespace nimbus::psf {
namespace {

std::vector<double> gaussian_kernel(double sigma, int radius) {
    std::vector<double> w(static_cast<size_t>(2 * radius + 1));
    double sum = 0.0;
    for (int i = -radius; i <= radius; ++i) {
        w[static_cast<size_t>(i + radius)] = std::exp(-0.5 * i * i / (sigma * sigma));
        sum += w[static_cast<size_t>(i + radius)];
    }
    for (double& v : w) v /= sum;
    return w;
}

// One separable pass along `axis` over f's owned cells; in-domain neighbours are read from f
// (owned or ghost), out-of-domain ones across the seam of a periodic axis (x, y: whole on every
// rank) or by half-sample reflection.
void blur_axis(Field<double>& f, const Int3& n, int axis, const std::vector<double>& kern, int radius,
               bool periodic) {
    const Box own = f.owned();
    const int nc = f.ncomp();
    Field<double> out(own, 0, nc, 0.0);
    std::vector<double> acc(static_cast<size_t>(nc));
    for_each_cell(own, [&](int i, int j, int k) {
        std::fill(acc.begin(), acc.end(), 0.0);
        int idx[3] = {i, j, k};
        const int centre = idx[axis];
        for (int o = -radius; o <= radius; ++o) {
            idx[axis] = periodic ? wrap_index(centre + o, n[axis]) : reflect_index(centre + o, n[axis]);
            const double w = kern[static_cast<size_t>(o + radius)];
            const double* p = &f(idx[0], idx[1], idx[2]);
            for (int c = 0; c < nc; ++c) acc[static_cast<size_t>(c)] += w * p[c];
        }
        double* q = &out(i, j, k);
        for (int c = 0; c < nc; ++c) q[c] = acc[static_cast<size_t>(c)];
    });
    for_each_cell(own, [&](int i, int j, int k) {
        const double* p = &out(i, j, k);
        double* q = &f(i, j, k);
        for (int c = 0; c < nc; ++c) q[c] = p[c];
    });
}

// Along one axis, the fine cells under coarse cell j and their weights |coarse ∩ fine ∩ domain|,
// normalized to sum 1 (pyramid.h, Centring). In fine cells from the fine level's first corner:
// the domain is [d_lo, d_lo + length/hf), coarse cell j is [c0 + 2j, c0 + 2j + 2).
struct AxisTaps {
    int first = 0, count = 0;
    double w[3] = {0.0, 0.0, 0.0};
};

std::vector<AxisTaps> axis_taps(int nf, double hf, double offset_f, int nc, double offset_c, double length) {
    const double d_lo = -offset_f / hf, d_hi = d_lo + length / hf, c0 = (offset_c - offset_f) / hf;
    std::vector<AxisTaps> taps(static_cast<size_t>(nc));
    for (int j = 0; j < nc; ++j) {
        const double lo = c0 + 2.0 * j, hi = lo + 2.0;
        AxisTaps& t = taps[static_cast<size_t>(j)];
        t.first = std::max(0, static_cast<int>(std::floor(lo)));
        double sum = 0.0;
        for (int i = t.first; i < std::min(nf, static_cast<int>(std::ceil(hi))) && t.count < 3; ++i) {
            const double w = std::max(0.0, std::min({hi, i + 1.0, d_hi}) - std::max({lo, static_cast<double>(i), d_lo}));
            t.w[t.count++] = w;
            sum += w;
        }
        if (!(sum > 0.0)) throw Error("psf pyramid: a coarse cell lies outside the domain");
        for (double& w : t.w) w /= sum;
    }
    return taps;
}

// Each coarse owned cell of `coarse`: the weighted mean of the fine cells under it (taps per axis).
void downsample(const Field<double>& fine, const std::array<std::vector<AxisTaps>, 3>& taps, Field<double>& coarse) {
    const int nc = fine.ncomp();
    const Box& fa = fine.allocated();
    for_each_cell(coarse.owned(), [&](int i, int j, int k) {
        const AxisTaps &tx = taps[0][static_cast<size_t>(i)], &ty = taps[1][static_cast<size_t>(j)],
                       &tz = taps[2][static_cast<size_t>(k)];
        double* q = &coarse(i, j, k);
        for (int c = 0; c < nc; ++c) q[c] = 0.0;
        for (int c2 = 0; c2 < tz.count; ++c2)
            for (int b = 0; b < ty.count; ++b)
                for (int a = 0; a < tx.count; ++a) {
                    const int x = tx.first + a, y = ty.first + b, z = tz.first + c2;
                    if (!fa.contains(x, y, z)) throw Error("psf pyramid: fine level does not cover its coarse cells");
                    const double w = tx.w[a] * ty.w[b] * tz.w[c2];
                    const double* p = &fine(x, y, z);
                    for (int c = 0; c < nc; ++c) q[c] += w * p[c];
                }
    });
}

Field<float> to_float(const Field<double>& f) {
    Field<float> out(f.owned(), f.ghost(), f.ncomp(), 0.0f);
    const double* src = f.data();
    float* dst = out.data();
    for (size_t i = 0; i < f.size(); ++i) dst[i] = static_cast<float>(src[i]);
    return out;
}

// Every rank's owned layers of a z-slab field (owned z ranges z_owned) on every rank.
Field<double> allgather_slabs(const Field<double>& f, const Int3& n,
                              const std::vector<std::pair<int, int>>& z_owned, MPI_Comm comm) {
    const int nc = f.ncomp();
    const long long layer = static_cast<long long>(n[0]) * n[1] * nc;
    const std::vector<double> mine = f.owned_values();
    std::vector<std::int64_t> counts, displs;
    for (const auto& [lo, hi] : z_owned) {
        displs.push_back(lo * layer);
        counts.push_back((hi - lo) * layer);
    }
    Field<double> all(Box{{0, 0, 0}, n}, 0, nc, 0.0);
    allgatherv_doubles(comm, mine, all.data(), counts, displs);
    return all;
}

}  // namespace

LightPyramid::LightPyramid(Field<double> level0, const Grid& g, const Decomposition& d, int max_levels)
    : ncomp_(level0.ncomp()), origin_(g.origin) {
    const MPI_Comm comm = d.comm();
    const int P = d.size();
    check_collective(comm, d.is_slab_z(), "model psf: the light pyramid needs slabs along z (grid.process_grid = [1, 1, P])");
    check_collective(comm, level0.ghost() >= 3 && level0.owned() == d.local(),
                     "model psf: the level-0 light volume must cover the rank's box with 3 ghost layers");
    exchange_halo(level0, d);

    // z is split over the ranks (slabs), so only x and y can be blurred across a periodic seam.
    check_collective(comm, !d.periodic(2), "model psf: grid.periodic z is not supported (its light pyramid "
                                           "is split into z slabs)");
    const std::array<bool, 3> periodic{d.periodic(0), d.periodic(1), false};
    PyramidLevel l0;
    l0.k = 0;
    l0.periodic = periodic;
    l0.n = g.n;
    l0.h = g.h;
    l0.replicated = P == 1;
    for (int p = 0; p < P; ++p) l0.z_owned.emplace_back(d.box_of(p).lo[2], d.box_of(p).hi[2]);
    l0.values = to_float(level0);
    levels_.push_back(std::move(l0));

    Field<double> prev = std::move(level0);
    bool prev_replicated = P == 1;
    for (int k = 1;; ++k) {
        const PyramidLevel& pl = levels_.back();
        if (std::max({pl.n[0], pl.n[1], pl.n[2]}) <= 2) break;
        if (max_levels > 0 && k >= max_levels) break;
        PyramidLevel lv;
        lv.k = k;
        lv.periodic = periodic;
        lv.h = 2.0 * pl.h;
        lv.width = lv.h;
        std::array<std::vector<AxisTaps>, 3> taps;
        std::array<std::vector<double>, 3> kern;
        int ghost = 3;
        for (int a = 0; a < 3; ++a) {
            const double length = g.n[a] * g.h;
            lv.n[a] = (pl.n[a] + 1) / 2;
            const bool centred = !periodic[a] && pl.n[a] % 2 == 1;
            lv.offset[a] = periodic[a] ? 0.0 : 0.5 * (length - lv.n[a] * lv.h);
            taps[a] = axis_taps(pl.n[a], pl.h, pl.offset[a], lv.n[a], lv.offset[a], periodic[a] ? pl.n[a] * pl.h : length);
            const double resample = centred ? 1.0 / 8.0 : 1.0 / 16.0;  // variance / h_k²
            lv.sigma[a] = std::sqrt(1.0 - pl.width * pl.width / (lv.h * lv.h) - resample);
            lv.radius[a] = static_cast<int>(std::ceil(4.0 * lv.sigma[a]));
            kern[a] = gaussian_kernel(lv.sigma[a], lv.radius[a]);
            ghost = std::max(ghost, lv.radius[a]);
        }
        bool distributed = !prev_replicated;
        for (int p = 0; p < P && distributed; ++p)
            distributed = Decomposition::split_lo(lv.n[2], P, p + 1) - Decomposition::split_lo(lv.n[2], P, p) >= ghost + 1;
        Field<double> cur;
        if (distributed) {
            const Decomposition dk(comm, lv.n);
            for (int p = 0; p < P; ++p) lv.z_owned.emplace_back(dk.box_of(p).lo[2], dk.box_of(p).hi[2]);
            cur = Field<double>(dk.local(), ghost, ncomp_, 0.0);
            std::string msg;
            try {
                downsample(prev, taps, cur);
            } catch (const Error& e) {
                msg = e.what();
            }
            check_collective(comm, msg.empty(), msg);
            blur_axis(cur, lv.n, 0, kern[0], lv.radius[0], periodic[0]);
            blur_axis(cur, lv.n, 1, kern[1], lv.radius[1], periodic[1]);
            exchange_halo(cur, dk);
            blur_axis(cur, lv.n, 2, kern[2], lv.radius[2], false);
            exchange_halo(cur, dk);
        } else {
            if (!prev_replicated) {
                prev = allgather_slabs(prev, pl.n, pl.z_owned, comm);
                prev_replicated = true;
            }
            lv.replicated = true;
            cur = Field<double>(Box{{0, 0, 0}, lv.n}, 0, ncomp_, 0.0);
            downsample(prev, taps, cur);
            for (int a = 0; a < 3; ++a) blur_axis(cur, lv.n, a, kern[a], lv.radius[a], periodic[a]);
        }
        lv.values = to_float(cur);
        levels_.push_back(std::move(lv));
        prev = std::move(cur);
    }
}

Field<float> gather_layers(const PyramidLevel& level, int need_lo, int need_hi, MPI_Comm comm) {
    if (level.replicated) return level.values;
    int rank = 0, P = 1;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &P);
    const Int3 n = level.n;
    need_lo = std::clamp(need_lo, 0, n[2]);
    need_hi = std::clamp(need_hi, need_lo, n[2]);
    int mine[2] = {need_lo, need_hi};
    std::vector<int> need(static_cast<size_t>(2 * P));
    MPI_Allgather(mine, 2, MPI_INT, need.data(), 2, MPI_INT, comm);
    const int nc = level.values.ncomp();
    const std::int64_t layer = static_cast<std::int64_t>(n[0]) * n[1] * nc;
    std::vector<std::int64_t> scount(static_cast<size_t>(P)), sdispl(static_cast<size_t>(P)),
        rcount(static_cast<size_t>(P)), rdispl(static_cast<size_t>(P));
    std::vector<float> send;
    const auto [olo, ohi] = level.z_owned[static_cast<size_t>(rank)];
    // The other ranks' layers go through the send buffer (reserved exactly: a growing vector
    // could hold twice them); this rank's own are copied straight into the result below.
    auto sent_layers = [&](int p) {
        return p == rank ? 0 : std::max(0, std::min(ohi, need[static_cast<size_t>(2 * p + 1)]) -
                                               std::max(olo, need[static_cast<size_t>(2 * p)]));
    };
    std::int64_t send_layers = 0;
    for (int p = 0; p < P; ++p) send_layers += sent_layers(p);
    send.reserve(static_cast<size_t>(send_layers * layer));
    for (int p = 0; p < P; ++p) {
        const int lo = std::max(olo, need[static_cast<size_t>(2 * p)]), hi = lo + sent_layers(p);
        sdispl[static_cast<size_t>(p)] = static_cast<std::int64_t>(send.size());
        for (int z = lo; z < hi; ++z)
            for (int y = 0; y < n[1]; ++y) {
                const float* v = &level.values(0, y, z);  // one x-row of owned cells is contiguous
                send.insert(send.end(), v, v + static_cast<std::ptrdiff_t>(n[0]) * nc);
            }
        scount[static_cast<size_t>(p)] = static_cast<std::int64_t>(send.size()) - sdispl[static_cast<size_t>(p)];
    }
    Field<float> out(Box{{0, 0, need_lo}, {n[0], n[1], need_hi}}, 0, nc, 0.0f);
    for (int p = 0; p < P; ++p) {
        const auto [plo, phi] = level.z_owned[static_cast<size_t>(p)];
        const int lo = std::max(plo, need_lo), hi = std::min(phi, need_hi);
        rdispl[static_cast<size_t>(p)] = std::max(0, lo - need_lo) * layer;
        rcount[static_cast<size_t>(p)] = p == rank ? 0 : std::max(0, hi - lo) * layer;
    }
    const BlockCounts sb(comm, scount, sdispl, MPI_FLOAT), rb(comm, rcount, rdispl, MPI_FLOAT);
    MPI_Alltoallv(send.data(), sb.counts(), sb.displs(), sb.type(), out.data(), rb.counts(), rb.displs(), rb.type(),
                  comm);
    for (int z = std::max(olo, need_lo); z < std::min(ohi, need_hi); ++z)
        for (int y = 0; y < n[1]; ++y)
            std::copy_n(&level.values(0, y, z), static_cast<std::ptrdiff_t>(n[0]) * nc, &out(0, y, z));
    return out;
}

void sample_level(const Field<float>& f, const PyramidLevel& level, const Vec3& origin, const Vec3& x,
                  float* out, int ncomp) {
    int i0[3], i1[3];
    double fr[3];
    const Box& a = f.allocated();
    for (int ax = 0; ax < 3; ++ax) {
        const double q = (x[ax] - origin[ax] - level.offset[ax]) / level.h - 0.5;
        const double fl = std::floor(q);
        fr[ax] = q - fl;
        if (level.periodic[ax]) {  // the neighbour across the seam
            i0[ax] = wrap_index(static_cast<int>(fl), level.n[ax]);
            i1[ax] = wrap_index(static_cast<int>(fl) + 1, level.n[ax]);
            continue;
        }
        const int lo = std::max(0, a.lo[ax]), hi = std::min(level.n[ax], a.hi[ax]) - 1;
        i0[ax] = std::clamp(static_cast<int>(fl), lo, hi);
        i1[ax] = std::clamp(static_cast<int>(fl) + 1, lo, hi);
    }
    const int nc = ncomp < 0 ? f.ncomp() : std::min(ncomp, f.ncomp());
    const float* p000 = &f(i0[0], i0[1], i0[2]);
    const std::ptrdiff_t dx = (i1[0] - i0[0]) * f.stride(0), dy = (i1[1] - i0[1]) * f.stride(1),
                         dz = (i1[2] - i0[2]) * f.stride(2);
    const double fx = fr[0], fy = fr[1], fz = fr[2];
    for (int c = 0; c < nc; ++c) {
        const float* p = p000 + c;
        const double c00 = p[0] + fx * (p[dx] - p[0]);
        const double c10 = p[dy] + fx * (p[dy + dx] - p[dy]);
        const double c01 = p[dz] + fx * (p[dz + dx] - p[dz]);
        const double c11 = p[dz + dy] + fx * (p[dz + dy + dx] - p[dz + dy]);
        const double b0 = c00 + fy * (c10 - c00), b1 = c01 + fy * (c11 - c01);
        out[c] = static_cast<float>(b0 + fz * (b1 - b0));
    }
}

}  // namespace nimbus::psf
