// The forward photon kernel: one path from a collimated light term through the replicated
// grid, with implicit capture, Russian roulette, the track-length fluence estimator and an
// optional forced first collision; and where the paths enter (EntrySampler, live pixels).
//
//   free path:   tau = -ln(xi), walked exactly through piecewise-constant kappa (grid_walk.h)
//   forced first collision (optional; Cashwell & Everett 1959; Lux & Koblinger 1991 ch. 5):
//                tau_tot = optical depth of the whole entry ray (one walk to the exit);
//                escaped_direct += exp(-tau_tot) (the expected uncollided part, analytic);
//                w = 1 - exp(-tau_tot); tau = -ln(1 - xi (1 - exp(-tau_tot))), i.e. the
//                exponential truncated to [0, tau_tot]; tau_tot = 0: nothing else to do.
//                Off by default (ForwardSettings): with the live-pixel entry below, on the
//                default cloud it costs ~30% more instructions per collision for ~4% less
//                variance per cell (~36% less for the total diffuse power)
//   collision:   absorbed += w (1 - a);  w *= a           (implicit capture)
//   roulette:    if w < w_min: survive with probability 1/2 and w *= 2, else end
//   scattering:  mu ~ HG(g) (hg_sample_mu), phi uniform; d = turn_direction(d, mu, cos phi, sin phi)
//   emitted:     a volume-source photon (trace_emitted_photon) starts with w = 1 inside the
//                medium and is tallied from its first segment (emitted light is diffuse)
//   estimator:   fluence_cell += w P len / V for every segment after the first scattering
//                (the unscattered beam E0 T is the reduced fluence: tallied only on request;
//                forced: as its expected value along the entry ray, uncollided_track);
//                flux: at each collision that ends such a segment (a diffuse flight),
//                flux_cell += w P d / (kappa V), w the weight before capture, d the flight's
//                direction, kappa the cell's extinction: the collision estimator. Collisions
//                along a length l of a flight in the cell number kappa l on average, so its
//                expectation is that of the track-length sum w P len d / V (the fluence's).
//
// Pure kernel: no MPI, no allocation; the caller owns the tally arrays.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "src/core/grid_walk.h"
#include "solvers/montecarlo/philox.h"
#include "solvers/montecarlo/sincos.h"
#include "src/physics/phase.h"

namespace nimbus::mc {

// The non-empty cells of a box of m cells (nonempty(c), box-relative c) that have an empty
// face neighbour or a face on the box's boundary (non-periodic axes; periodic axes wrap): a ray
// from outside the box that meets a non-empty cell meets one of these first (it crosses faces).
template <class NonEmpty>
std::vector<std::array<int, 3>> surface_cells(const std::array<int, 3>& m, const std::array<bool, 3>& periodic,
                                              NonEmpty&& nonempty) {
    std::vector<std::array<int, 3>> out;
    std::array<int, 3> c;
    for (c[2] = 0; c[2] < m[2]; ++c[2])
        for (c[1] = 0; c[1] < m[1]; ++c[1])
            for (c[0] = 0; c[0] < m[0]; ++c[0]) {
                if (!nonempty(c)) continue;
                bool surface = false;
                for (int a = 0; a < 3 && !surface; ++a)
                    for (int dir = -1; dir <= 1 && !surface; dir += 2) {
                        std::array<int, 3> nb = c;
                        nb[a] += dir;
                        if (nb[a] < 0 || nb[a] >= m[a]) {
                            if (!periodic[a]) { surface = true; continue; }
                            nb[a] = (nb[a] + m[a]) % m[a];
                        }
                        surface = !nonempty(nb);
                    }
                if (surface) out.push_back(c);
            }
    return out;
}

// Where the photons of one light term enter: the faces of `box` (the bounding box of the
// non-empty cells; the domain along periodic axes) that the beam crosses inward, chosen with
// probability |n·w| area / A_projected and uniformly over the face (grid units). Rays that miss
// the box cross only empty cells and leave unscattered, so starting on the box is exact; the
// caller books the rest of the domain's projected area as direct escape. sample() gives the
// cell in the walked grid (grid_walk.h: the box itself, or the domain when empty cells are
// tallied; GridView::origin).
//
// restrict_to(nonempty) narrows the entry further to the live pixels (cell-sized squares) of
// each face: those whose rays can reach a non-empty cell. A pixel is live if it meets the
// projection along w onto the face's plane of some non-empty cell (conservative: a ray through
// a dead pixel meets only empty cells, so it leaves unscattered, tau_tot = 0); the faces'
// weights and projected_area then count only live pixels, so the caller books the dead area as
// direct escape like the area outside the box. Photons are uniform over the live pixels.
struct EntrySampler {
    int nfaces = 0;
    int face[3]{};                 // face indices (grid_walk.h numbering)
    double cumulative[3]{};        // cumulative probabilities
    double projected_area = 0.0;   // A_projected of the (live part of the) box in cells² (× h² for m²)
    std::array<int, 3> lo{0, 0, 0}, hi{0, 0, 0};
    bool masked[3]{};                   // per face: sampled over its live pixels only
    std::vector<std::int32_t> live[3];  // per masked face: live pixels u + m_u v (u, v: the next two axes)

    EntrySampler(const std::array<int, 3>& box_lo, const std::array<int, 3>& box_hi,
                 const std::array<bool, 3>& periodic, const Vec3& w)
        : lo(box_lo), hi(box_hi) {
        double weight[3]{};
        for (int a = 0; a < 3; ++a) {
            if (periodic[a] || w[a] == 0.0) continue;
            const double area = static_cast<double>(hi[(a + 1) % 3] - lo[(a + 1) % 3]) *
                                (hi[(a + 2) % 3] - lo[(a + 2) % 3]);
            if (area <= 0) continue;
            face[nfaces] = face_index(a, w[a] < 0);  // travelling down enters through the top
            weight[nfaces] = std::abs(w[a]) * area;
            ++nfaces;
        }
        set_weights(weight);
    }

    // surface: box-relative cells (in [0, hi - lo)) that include every non-empty cell a ray from
    // outside can reach first (surface_cells); periodic as in the constructor.
    void restrict_to(const std::vector<std::array<int, 3>>& surface, const std::array<bool, 3>& periodic,
                     const Vec3& w) {
        const std::array<int, 3> m{hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
        double weight[3]{};
        for (int f = 0; f < nfaces; ++f) {
            const int a = face[f] / 2, ax[2] = {(a + 1) % 3, (a + 2) % 3};
            const int mu = m[ax[0]], mv = m[ax[1]];
            const double plane = face[f] % 2 == 1 ? m[a] : 0.0;
            // 2-D difference array of rectangle marks, (mu + 1) x (mv + 1).
            std::vector<std::int32_t> mark(static_cast<size_t>(mu + 1) * (mv + 1), 0);
            auto add_rect = [&](int u0, int u1, int v0, int v1) {
                mark[static_cast<size_t>(v0) * (mu + 1) + u0] += 1;
                mark[static_cast<size_t>(v0) * (mu + 1) + u1 + 1] -= 1;
                mark[static_cast<size_t>(v1 + 1) * (mu + 1) + u0] -= 1;
                mark[static_cast<size_t>(v1 + 1) * (mu + 1) + u1 + 1] += 1;
            };
            // Pixel ranges per face axis, as at most two [first, last] pieces inside [0, m).
            auto pieces = [&](int b, double y0, double y1, int (*out)[2]) {
                const int mb = m[b];
                int p0 = floor_to_int(y0), p1 = floor_to_int(y1);
                if (!periodic[b]) {
                    p0 = std::max(p0, 0), p1 = std::min(p1, mb - 1);
                    if (p0 > p1) return 0;
                    out[0][0] = p0, out[0][1] = p1;
                    return 1;
                }
                if (p1 - p0 + 1 >= mb) {
                    out[0][0] = 0, out[0][1] = mb - 1;
                    return 1;
                }
                p0 = ((p0 % mb) + mb) % mb;
                p1 = ((p1 % mb) + mb) % mb;
                if (p0 <= p1) {
                    out[0][0] = p0, out[0][1] = p1;
                    return 1;
                }
                out[0][0] = p0, out[0][1] = mb - 1, out[1][0] = 0, out[1][1] = p1;
                return 2;
            };
            const double k[2] = {w[ax[0]] / w[a], w[ax[1]] / w[a]};
            for (const std::array<int, 3>& c : surface) {
                // Corner x projects to y_b = x_b - (x_a - plane) k_b: a rectangle of pixels.
                const double s0 = c[a] - plane, s1 = c[a] + 1 - plane;
                int r[2][2][2], nr[2];
                for (int q = 0; q < 2; ++q) {
                    const double d0 = s0 * k[q], d1 = s1 * k[q];
                    nr[q] = pieces(ax[q], c[ax[q]] - std::max(d0, d1), c[ax[q]] + 1 - std::min(d0, d1), r[q]);
                }
                for (int x = 0; x < nr[0]; ++x)
                    for (int y = 0; y < nr[1]; ++y) add_rect(r[0][x][0], r[0][x][1], r[1][y][0], r[1][y][1]);
            }
            // Prefix sums: the count of rectangles over each pixel.
            for (int v = 0; v <= mv; ++v)
                for (int u = 0; u <= mu; ++u) {
                    std::int32_t& x = mark[static_cast<size_t>(v) * (mu + 1) + u];
                    if (u > 0) x += mark[static_cast<size_t>(v) * (mu + 1) + u - 1];
                    if (v > 0) x += mark[static_cast<size_t>(v - 1) * (mu + 1) + u];
                    if (u > 0 && v > 0) x -= mark[static_cast<size_t>(v - 1) * (mu + 1) + u - 1];
                }
            live[f].clear();
            for (int v = 0; v < mv; ++v)
                for (int u = 0; u < mu; ++u)
                    if (mark[static_cast<size_t>(v) * (mu + 1) + u] > 0) live[f].push_back(u + mu * v);
            weight[f] = std::abs(w[a]) * static_cast<double>(live[f].size());
            // A face that is all live keeps the unmasked sampling (the same draws as without it).
            masked[f] = static_cast<std::int64_t>(live[f].size()) < static_cast<std::int64_t>(mu) * mv;
            if (!masked[f]) live[f].clear();
        }
        // Faces without live pixels are dropped (never sampled).
        int kept = 0;
        for (int f = 0; f < nfaces; ++f) {
            if (weight[f] <= 0) continue;
            face[kept] = face[f];
            weight[kept] = weight[f];
            masked[kept] = masked[f];
            if (kept != f) live[kept].swap(live[f]);
            ++kept;
        }
        nfaces = kept;
        set_weights(weight);
    }

    [[gnu::always_inline]] void sample(PathRng& rng, const GridView& grid, PathState& s) const {
        const double xi = rng.uniform();
        int f = 0;
        while (f < nfaces - 1 && xi > cumulative[f]) ++f;
        const int axis = face[f] / 2;
        const bool high = face[f] % 2 == 1;
        int pixel[3] = {0, 0, 0};  // box-relative pixel on the masked face
        std::array<int, 3> cell{};
        if (masked[f]) {
            const int nlive = static_cast<int>(live[f].size());
            const int p = live[f][static_cast<size_t>(std::min(static_cast<int>(rng.uniform() * nlive), nlive - 1))];
            const int mu = hi[(axis + 1) % 3] - lo[(axis + 1) % 3];
            pixel[(axis + 1) % 3] = p % mu;
            pixel[(axis + 2) % 3] = p / mu;
        }
        for (int a = 0; a < 3; ++a) {
            if (a == axis) {
                cell[a] = high ? hi[a] - 1 - lo[a] : 0;
                s.frac[a] = high ? 1.0 : 0.0;
            } else if (masked[f]) {
                cell[a] = pixel[a];
                s.frac[a] = rng.uniform();
            } else {
                const double u = lo[a] + rng.uniform() * (hi[a] - lo[a]);
                const int c = std::min(static_cast<int>(u), hi[a] - 1);
                s.frac[a] = u - c;
                cell[a] = c - lo[a];
            }
        }
        for (int a = 0; a < 3; ++a) cell[a] += lo[a] - grid.origin[a];  // box-relative to the walked grid's
        s.idx = grid.index(cell);
    }

private:
    void set_weights(const double weight[3]) {
        projected_area = 0.0;
        for (int f = 0; f < nfaces; ++f) projected_area += weight[f];
        double acc = 0.0;
        for (int f = 0; f < nfaces; ++f) cumulative[f] = projected_area > 0 ? (acc += weight[f] / projected_area) : 1.0;
        if (nfaces > 0) cumulative[nfaces - 1] = 1.0;
    }
};

// The direction at polar cosine mu and azimuth (cos_phi, sin_phi) around unit w: rotate_direction
// of src/physics/phase.h with the azimuth's cosine and sine given (sincos.h computes them).
[[gnu::always_inline]] inline Vec3 turn_direction(const Vec3& w, double mu, double cos_phi, double sin_phi) {
    Vec3 u, v;
    orthonormal_basis(w, u, v);
    const double s = std::sqrt(std::max(0.0, 1.0 - mu * mu));
    return u * (s * cos_phi) + v * (s * sin_phi) + w * mu;
}

// Per-path outcome in photon-weight units (the caller scales by the photon power).
struct PathTally {
    double absorbed = 0.0;
    double roulette_net = 0.0;        // weight created (+) or destroyed (-) by roulette
    double escaped_direct = 0.0;      // left the domain without scattering
    double escaped_diffuse[6]{};      // left through each face after >= 1 scattering
    std::int64_t collisions = 0;
    std::int64_t segments = 0;        // diffuse track segments tallied (cells crossed with a tally)
};

struct PhotonOptics {
    double albedo = 0.9, g = 0.85, roulette_weight = 0.05;
};

// Expected track length (cells) of the uncollided beam of unit weight in one segment of
// length len and extinction kappa > 0 entered at optical depth tau_in: the integral of
// exp(-tau_in - kappa x) over [0, len] (Beer-Lambert).
inline double uncollided_track(double tau_in, double kappa, double len) {
    return std::exp(-tau_in) * (-std::expm1(-kappa * len)) / kappa;
}

// Continues a path of weight w from its collision at s until it leaves the domain or ends:
// implicit capture, roulette, HG scattering, the next free flight (tallied as diffuse).
// tally_collision(idx, w) is called at every collision that ends a diffuse flight (the first
// one too when `diffuse`), before the capture, with s.d the flight's direction. kEmptyCells: the
// flights' segments in empty cells are tallied too (walk_optical_depth).
template <bool kEmptyCells = false, class TallyDiffuse, class TallyCollision>
[[gnu::always_inline]] inline void scatter_path(const GridView& grid, const PhotonOptics& o, PathRng& rng, PathState& s,
                         PathTally& out, double w, TallyDiffuse&& tally_diffuse, TallyCollision&& tally_collision,
                         bool diffuse) {
    for (;;) {
        if (diffuse) tally_collision(s.idx, w);
        diffuse = true;
        ++out.collisions;
        out.absorbed += w * (1.0 - o.albedo);
        w *= o.albedo;
        if (w <= 0.0) return;
        if (w < o.roulette_weight) {
            if (rng.uniform() < 0.5) {
                out.roulette_net += w;
                w *= 2.0;
            } else {
                out.roulette_net -= w;
                return;
            }
        }
        const double mu = hg_sample_mu(o.g, rng.uniform());
        double cos_phi, sin_phi;
        sincos_2pi(rng.uniform(), cos_phi, sin_phi);  // phi = 2π xi
        s.d = turn_direction(s.d, mu, cos_phi, sin_phi);
        const double tau = -std::log(rng.uniform());
        const int face =
            walk_optical_depth<kEmptyCells>(grid, s, tau, [&](std::int64_t idx, double len) { tally_diffuse(idx, w * len); });
        if (face >= 0) {
            out.escaped_diffuse[face] += w;
            return;
        }
    }
}

// Traces one path from state s (already at its entry point). tally_diffuse(idx, w_len) is
// called per segment after the first scattering, tally_collision(idx, w) at each collision
// after the first (scatter_path); tally_reduced(idx, track) per uncollided
// segment if tally_reduced_on: the analog track length before the first collision, or with
// `forced` the expected uncollided track (uncollided_track) over the whole entry ray. A forced
// path costs one walk of its entry ray (tau_tot) plus the walk to its collision. kEmptyCells: as
// scatter_path's (the uncollided flight, not tallied as diffuse, keeps its empty-space jumps).
template <bool tally_reduced_on = false, bool kEmptyCells = false, class TallyDiffuse, class TallyCollision,
          class TallyReduced>
[[gnu::always_inline]] inline void trace_photon(const GridView& grid, const PhotonOptics& o, PathRng& rng, PathState& s,
                         PathTally& out, TallyDiffuse&& tally_diffuse, TallyCollision&& tally_collision,
                         TallyReduced&& tally_reduced, bool forced = false) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    double w = 1.0;
    if (forced) {
        double tau_tot = 0.0;
        PathState exit = s;
        walk_optical_depth(grid, exit, inf, [&](std::int64_t idx, double len) {
            const double kappa = grid.voxel[idx].kappa;
            if constexpr (tally_reduced_on) tally_reduced(idx, uncollided_track(tau_tot, kappa, len));
            tau_tot += kappa * len;
        });
        out.escaped_direct += std::exp(-tau_tot);
        w = -std::expm1(-tau_tot);  // probability of a collision on the entry ray
        if (!(w > 0.0)) return;
        // Its depth is below tau_tot, so the walk ends inside unless round-off of the two sums
        // says otherwise (then the weight leaves as uncollided).
        const double tau_first = -std::log1p(-rng.uniform() * w);
        if (walk_optical_depth(grid, s, tau_first, [](std::int64_t, double) {}) >= 0) {
            out.escaped_direct += w;
            return;
        }
    } else {
        const double tau_first = -std::log(rng.uniform());
        const int face = walk_optical_depth(grid, s, tau_first, [&](std::int64_t idx, double len) {
            if constexpr (tally_reduced_on) tally_reduced(idx, len);
        });
        if (face >= 0) {
            out.escaped_direct += w;
            return;
        }
    }
    scatter_path<kEmptyCells>(grid, o, rng, s, out, w, tally_diffuse, tally_collision, false);
}

// A photon of a volume source (emitter.h): starts at s (inside an emitting cell, direction
// s.d) with weight 1. All emitted light is diffuse light (DESIGN §1), so its track (and its
// first collision) is tallied from the start; an emitted photon that leaves uncollided is
// booked in escaped_diffuse. kEmptyCells: as scatter_path's.
template <bool kEmptyCells = false, class TallyDiffuse, class TallyCollision>
[[gnu::always_inline]] inline void trace_emitted_photon(const GridView& grid, const PhotonOptics& o, PathRng& rng, PathState& s,
                                 PathTally& out, TallyDiffuse&& tally_diffuse, TallyCollision&& tally_collision) {
    const double tau = -std::log(rng.uniform());
    const int face =
        walk_optical_depth<kEmptyCells>(grid, s, tau, [&](std::int64_t idx, double len) { tally_diffuse(idx, len); });
    if (face >= 0) {
        out.escaped_diffuse[face] += 1.0;
        return;
    }
    scatter_path<kEmptyCells>(grid, o, rng, s, out, 1.0, tally_diffuse, tally_collision, true);
}

}  // namespace nimbus::mc
