// Render load balance: re-partitions the z-layers of the view volume between the ranks of a
// slab decomposition so that each rank marches about the same number of samples.
//
// Why: the march cost of a rank is its number of trilinear samples, which lives only in the
// occupied blocks of its box; with equal slabs the rank holding the cloud's dense base did ~2x
// the work of the other. The view volume (view_volume.h) is a pure function of the global cell,
// so any contiguous split of the layers renders the same image (march.h: the step lattice and
// the owner test depend only on the camera and the global grid).
//
// Work estimate of one cell in an occupied block (a pinhole camera, no early termination):
// the rays per unit area across the view direction at distance r are 1 / (r² Ω_pix) with the
// pixel solid angle Ω_pix = Ω_0 cos³θ off the optical axis (flat image plane), and each ray
// takes h / ds samples in a cell, so samples ∝ 1 / (r² cos³θ) for a cell whose centre projects
// into the image, 0 otherwise. Evaluated once per 8³ block at its centre (cells x estimate).
//
// Samples alone under-count: per ray, the box tests, the lattice set-up and the empty-block
// skips cost about as much again and depend on the box, not on the density. On the default
// cumulus (128³, 1920×1080, 2 ranks) a split by samples alone left the top rank marching
// 1.3-1.5x longer than the bottom one, so balance_view_volume adds the mean per-layer sample
// work to every layer (an empirical fixed cost per layer) before splitting.
//
// Split: contiguous ranges of layers, one per rank in rank order (rank 0 keeps layer 0, the
// ground), each at least one layer, cut where the prefix sum of the work crosses p/P of the
// total, at the layer boundary nearest that target (so, unless the one-layer minimum forces a
// cut, every part's work is within one layer's work of the mean).
#pragma once

#include <vector>

#include "src/core/decomposition.h"
#include "src/render/camera.h"
#include "src/render/view_volume.h"

namespace nimbus {

// Pure. Boundaries b[0] = 0 < b[1] < ... < b[nparts] = weight.size() of nparts contiguous
// ranges of layers [b[p], b[p+1]) with the prefix-quantile cut described above; weights must be
// >= 0, weight.size() >= nparts >= 1. All-zero weights give the even split floor(n p / P).
std::vector<int> balanced_split(const std::vector<double>& weight, int nparts);

// Pure. Estimated march samples per z-layer of v.owned (index k - v.owned.lo[2]), from v's
// occupancy blocks and the camera (the footprint weight above).
std::vector<double> march_work_per_layer(const ViewVolume& v, const Camera& camera);

// Collective over d.comm(). When d is a slab decomposition along z with more than one rank,
// moves layers of the view volume between ranks (point-to-point) so that each rank owns the
// balanced_split of the global march work, then rebuilds the occupancy; the returned volume's
// owned box is the rank's new box (x and y unchanged, at least one layer). Otherwise returns
// v unchanged. v must be build_view_volume's result on d.
ViewVolume balance_view_volume(ViewVolume v, const Decomposition& d, const Camera& camera);

}  // namespace nimbus
