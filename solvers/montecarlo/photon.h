// The forward photon kernel: one path from a collimated light term through the replicated
// grid, with implicit capture, Russian roulette and the track-length fluence estimator.
//
//   free path:   tau = -ln(xi), walked exactly through piecewise-constant kappa (grid_walk.h)
//   collision:   absorbed += w (1 - a);  w *= a           (implicit capture)
//   roulette:    if w < w_min: survive with probability 1/2 and w *= 2, else end
//   scattering:  mu ~ HG(g) (hg_sample_mu), phi uniform; d = turn_direction(d, mu, cos phi, sin phi)
//   estimator:   fluence_cell += w P len / V for every segment after the first scattering
//                (the unscattered beam E0 T is the reduced fluence, not tallied here)
//
// Pure kernel: no MPI, no allocation; the caller owns the tally arrays.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "solvers/montecarlo/grid_walk.h"
#include "solvers/montecarlo/philox.h"
#include "solvers/montecarlo/sincos.h"
#include "src/physics/phase.h"

namespace nimbus::mc {

// Where the photons of one light term enter: the faces of `box` (the bounding box of the
// non-empty cells; the domain along periodic axes) that the beam crosses inward, chosen with
// probability |n·w| area / A_projected and uniformly over the face (grid units). Rays that miss
// the box cross only empty cells and leave unscattered, so starting on the box is exact; the
// caller books the rest of the domain's projected area as direct escape. sample() gives the
// cell relative to the box (the walk's grid covers only the box, grid_walk.h).
struct EntrySampler {
    int nfaces = 0;
    int face[3]{};                 // face indices (grid_walk.h numbering)
    double cumulative[3]{};        // cumulative probabilities
    double projected_area = 0.0;   // A_projected of the box in cells² (multiply by h² for m²)
    std::array<int, 3> lo{0, 0, 0}, hi{0, 0, 0};

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
            projected_area += weight[nfaces];
            ++nfaces;
        }
        double acc = 0.0;
        for (int f = 0; f < nfaces; ++f) cumulative[f] = (acc += weight[f] / projected_area);
        if (nfaces > 0) cumulative[nfaces - 1] = 1.0;
    }

    void sample(PathRng& rng, PathState& s) const {
        const double xi = rng.uniform();
        int f = 0;
        while (f < nfaces - 1 && xi > cumulative[f]) ++f;
        const int axis = face[f] / 2;
        const bool high = face[f] % 2 == 1;
        for (int a = 0; a < 3; ++a) {
            if (a == axis) {
                s.cell[a] = high ? hi[a] - 1 - lo[a] : 0;
                s.frac[a] = high ? 1.0 : 0.0;
            } else {
                const double u = lo[a] + rng.uniform() * (hi[a] - lo[a]);
                const int c = std::min(static_cast<int>(u), hi[a] - 1);
                s.frac[a] = u - c;
                s.cell[a] = c - lo[a];
            }
        }
    }
};

// The direction at polar cosine mu and azimuth (cos_phi, sin_phi) around unit w: rotate_direction
// of src/physics/phase.h with the azimuth's cosine and sine given (sincos.h computes them).
inline Vec3 turn_direction(const Vec3& w, double mu, double cos_phi, double sin_phi) {
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
    double diffuse_track = 0.0;       // sum of w len (cells) after the first scattering
    std::int64_t collisions = 0;
};

struct PhotonOptics {
    double albedo = 0.9, g = 0.85, roulette_weight = 0.05;
};

// Traces one path from state s (already at its entry point). tally_diffuse(idx, w_len) is
// called per segment after the first scattering, tally_reduced(idx, len) per segment before it.
template <class TallyDiffuse, class TallyReduced>
inline void trace_photon(const GridView& grid, const PhotonOptics& o, PathRng& rng, PathState& s,
                         PathTally& out, TallyDiffuse&& tally_diffuse, TallyReduced&& tally_reduced) {
    double w = 1.0;
    bool scattered = false;
    for (;;) {
        const double tau = -std::log(rng.uniform());
        int face;
        if (scattered) {
            face = walk_optical_depth(grid, s, tau, [&](std::int64_t idx, double len) {
                tally_diffuse(idx, w * len);
                out.diffuse_track += w * len;
            });
        } else {
            face = walk_optical_depth(grid, s, tau, tally_reduced);
        }
        if (face >= 0) {
            if (scattered) out.escaped_diffuse[face] += w; else out.escaped_direct += w;
            return;
        }
        ++out.collisions;
        out.absorbed += w * (1.0 - o.albedo);
        w *= o.albedo;
        if (w <= 0.0) return;
        scattered = true;
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
    }
}

}  // namespace nimbus::mc
