// Sort-last compositing by direct send (DESIGN §2, §3).
//
// Each rank's ray march leaves, per pixel its box covers, a fragment: premultiplied radiance
// C_b and transmittance T_b per band of its piece of the view ray, and a sort key (the index of
// its first step on the ray's global step lattice, so keys order the pieces front to back).
// A pixel may also get one opaque background fragment (the lit ground), which sorts last.
// The image rows are split among the ranks; fragments go to their row's owner in one
// MPI_Alltoallv; the owner composites each pixel front to back with the "over" operator
//   C = C_front + T_front C_back,   T = T_front T_back            (Max 1995 §4.1)
// and finally adds the background: the ground fragment's radiance, or else `sky`, times T.
// Rank 0 gathers the rows (MPI_Gatherv). Image: bands -> RGB (1 band: gray, 3 bands: rgb),
// alpha = 1 - T averaged over bands (the volume's opacity; the background does not count).
#pragma once

#include <mpi.h>

#include <cstdint>
#include <limits>
#include <vector>

#include "src/render/image.h"

namespace nimbus {

class FragmentBuffer {
public:
    static constexpr std::int32_t kBackgroundKey = std::numeric_limits<std::int32_t>::max();

    explicit FragmentBuffer(int nbands) : nbands_(nbands) {}
    // A piece of pixel `pixel`'s view ray (row-major pixel index); C, T: nbands values each.
    void add_segment(std::int32_t pixel, std::int32_t key, const double* C, const double* T);
    // The opaque background seen by pixel `pixel` (radiance L per band), behind every segment.
    void add_background(std::int32_t pixel, const double* L);

    int nbands() const { return nbands_; }
    int record_words() const { return 2 + 2 * nbands_; }  // pixel, key, C[nb], T[nb]
    std::size_t size() const { return words_.size() / static_cast<size_t>(record_words()); }
    const std::vector<std::uint32_t>& words() const { return words_; }

private:
    int nbands_;
    std::vector<std::uint32_t> words_;
};

// Front-to-back "over" of a fragment (c, t) behind the accumulated (C, T), per band.
inline void composite_over(int nbands, double* C, double* T, const float* c, const float* t) {
    for (int b = 0; b < nbands; ++b) {
        C[b] += T[b] * c[b];
        T[b] *= t[b];
    }
}

// Collective over comm. Composites every rank's fragments into a width x height image with
// background radiance sky[b] (one value per band) behind pixels without a ground fragment.
// Returns the image on rank 0, an empty Image elsewhere. nbands must be 1 or 3.
Image composite_image(const FragmentBuffer& local, int width, int height,
                      const std::vector<double>& sky, MPI_Comm comm);

}  // namespace nimbus
