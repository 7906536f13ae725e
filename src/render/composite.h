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
// With a view-path source (view_source.h, march_source.h) each segment also carries A_b,
// H_spec,b, H_last,b and two flags; per pixel the compositor carries the held source value H
// front to back (H unset before the first piece with medium):
//   H_use = H set ? H : (piece has medium ? H_spec : 0);  C += T_front (c + A H_use);
//   then H = piece has a sample point ? H_last : H_use.
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

    // held_source: records carry the view-path source terms (add_segment_held).
    explicit FragmentBuffer(int nbands, bool held_source = false)
        : nbands_(nbands), held_(held_source) {}
    // A piece of pixel `pixel`'s view ray (row-major pixel index); C, T: nbands values each.
    void add_segment(std::int32_t pixel, std::int32_t key, const double* C, const double* T);
    // As add_segment, plus A, H_spec, H_last (nbands each) and the flags has_spec, has_sample.
    void add_segment_held(std::int32_t pixel, std::int32_t key, const double* C, const double* T,
                          const double* A, const double* H_spec, const double* H_last,
                          bool has_spec, bool has_sample);
    // The opaque background seen by pixel `pixel` (radiance L per band), behind every segment.
    void add_background(std::int32_t pixel, const double* L);

    int nbands() const { return nbands_; }
    bool held_source() const { return held_; }
    // pixel, key, C[nb], T[nb] (+ A[nb], H_spec[nb], H_last[nb], flags when held_source)
    int record_words() const { return 2 + 2 * nbands_ + (held_ ? 3 * nbands_ + 1 : 0); }
    std::size_t size() const { return words_.size() / static_cast<size_t>(record_words()); }
    const std::vector<std::uint32_t>& words() const { return words_; }

private:
    void push_floats(const double* v);
    void pad_held();
    int nbands_;
    bool held_ = false;
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
