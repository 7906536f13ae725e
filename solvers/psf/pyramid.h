// The light-volume pyramid (Premoze et al. 2004, Algorithm 1 BuildVolumePyramid, §5): a 3-D
// mip-map of a cell field (here the light volume T_l of every light term, one component each).
//   level 0: the field itself, blur width w_0 = 0;
//   level k: level k-1 resampled to half the resolution (cell h_k = 2^k h, each coarse cell the
//            mean of the fine cells over the part of it inside the domain), then a separable
//            Gaussian of standard deviation sigma_k coarse cells (truncated at ceil(4 sigma_k),
//            renormalized), with half-sample reflecting boundaries.
// Centring: on an open axis every level's cells are centred on the domain, so that the pyramid
// is symmetric under the domain's mirrors. Where level k-1 has an odd count n along the axis,
// level k has (n + 1)/2 cells starting half a fine cell before it (offset), each covering fine
// cells 2j-1 (half), 2j, 2j+1 (half); an even count halves from the start as before. (Halving
// from the origin made a centred sphere 3-12% mirror-asymmetric on odd grids.) Periodic axes
// halve from the origin (offset 0).
// The blur width (standard deviation per axis, metres) of level k relative to level 0 (cell
// values read as samples at cell centres): the resampling adds r h_k², r = 1/16 for the 2-cell
// mean at ±h_{k-1}/2 and 1/8 for the (1/4, 1/2, 1/4) mean of an odd count, so per axis
//   w_k² = w_{k-1}² + r h_k² + (sigma_k h_k)²,  sigma_k chosen so that w_k = h_k
// (sigma_1² = 15/16 or 14/16, sigma_k² = 11/16 or 10/16 for k >= 2).
// Energy: the resampling preserves Σ value × (cell volume inside the domain) exactly; the
// reflecting, normalized blur preserves Σ value × (whole cell volume), so levels are exact where
// every cell lies inside the domain (sizes divisible by 2^k) and close otherwise.
//
// Distribution (slabs along z): a level stays distributed while every rank's slab of it is at
// least (ghost + 1) layers thick, with ghost = max(kernel radius, 3) layers filled by the halo
// exchange (src/core/halo.h); coarser levels are replicated on every rank (gathered once).
// Other process grids are refused (the LightPyramid constructor: slabs along z only).
#pragma once

#include <array>

#include <memory>
#include <utility>
#include <vector>

#include "src/core/decomposition.h"
#include "src/core/field.h"
#include "src/core/grid.h"
#include "src/core/vec3.h"

namespace nimbus::psf {

struct PyramidLevel {
    int k = 0;
    Int3 n{0, 0, 0};          // cells per axis
    double h = 1.0;           // cell edge, metres
    Vec3 offset{0.0, 0.0, 0.0};  // the level's first cell corner minus the grid origin, metres (<= 0)
    double width = 0.0;       // blur width w_k, metres
    std::array<double, 3> sigma{0.0, 0.0, 0.0};  // Gaussian standard deviation per axis, level cells
                                                 // (0 for level 0)
    std::array<int, 3> radius{0, 0, 0};          // kernel radius per axis, level cells
    bool replicated = false;  // whole level on every rank
    std::array<bool, 3> periodic{false, false, false};  // the domain's periodic axes: blurred and
                                                        // sampled across the seam (else mirrored, clamped)
    std::vector<std::pair<int, int>> z_owned;  // per rank: owned z-layers [lo, hi) (distributed)
    Field<float> values;      // owned box + ghost (distributed) or the whole level (replicated)
};

class LightPyramid {
public:
    LightPyramid() = default;
    // Collective over d.comm(). level0: d.local() with ghost >= 3 (owned cells are read; the
    // ghosts are exchanged here), ncomp components. max_levels = 0: down to <= 2 cells per axis.
    LightPyramid(Field<double> level0, const Grid& g, const Decomposition& d, int max_levels);

    int size() const { return static_cast<int>(levels_.size()); }
    const PyramidLevel& level(int k) const { return levels_[static_cast<size_t>(k)]; }
    int ncomp() const { return ncomp_; }
    Vec3 origin() const { return origin_; }

private:
    std::vector<PyramidLevel> levels_;
    int ncomp_ = 1;
    Vec3 origin_;
};

// Collective over comm. The z-layers [need_lo, need_hi) (clamped to [0, n_z)) of a distributed
// level, gathered from their owners; replicated levels are returned whole.
Field<float> gather_layers(const PyramidLevel& level, int need_lo, int need_hi, MPI_Comm comm);

// Trilinear interpolation between the cell centres of a level (grid origin + level.offset +
// (i + 1/2) level.h) at world x (clamped to the edge cells, or wrapped on the level's periodic
// axes, which f must hold whole); f must hold the 2x2x2 stencil. out: the first ncomp values (-1: f.ncomp()). Pure.
void sample_level(const Field<float>& f, const PyramidLevel& level, const Vec3& origin, const Vec3& x,
                  float* out, int ncomp = -1);

// Index i wrapped into [0, n) (periodic axes).
inline int wrap_index(int i, int n) {
    const int m = i % n;
    return m < 0 ? m + n : m;
}

// Half-sample reflection of index i into [0, n).
inline int reflect_index(int i, int n) {
    const int p = 2 * n;
    int m = i % p;
    if (m < 0) m += p;
    return m < n ? m : p - 1 - m;
}

}  // namespace nimbus::psf
