// The per-row deposit kernel of a light propagation map (Fattal 2009 eq. 5, the sum over the
// map directions). Pure, no MPI, no allocation.
//
// After a step, phi_l[i] holds the path integral of map direction l in cell i of one row
// (W/m², already times |Ω^n|/R²). Everything the step deposits into a cell is a linear
// combination of those over the directions, with one coefficient column per output c:
//   out[c][i] = Σ_l C[l][c] phi_l[i],
// columns: 1 (the fluence), ω̄^n (the flux F, 3 columns, when asked for) and P^{n,m}/|Ω^m| per
// coarse bin m (the scattered light, eq. 5; omitted when the rows of P are all equal, i.e.
// isotropic scattering, where the fluence column times one row suffices).
// The phi rows are zeroed (they are the next step's accumulators).
#pragma once

#include <cstddef>

namespace nimbus::lpm {

// out: nc columns of n values, column c at out + c * out_stride (overwritten). phi: nl rows of
// n values, row l at phi + l * stride (zeroed on return). C: row l at C + l * c_stride, its
// first nc entries used (so a caller may ask for only the leading columns). Cells are
// independent; the sum over l runs in the order l = 0, 1, ..., nl - 1 for every output (so
// results do not depend on the blocking). Vectorized (x86-64-v3 clone, with FMA, chosen at
// run time where the CPU has it).
void gather_directions(int n, int nl, double* phi, std::size_t stride, const double* C, int c_stride, int nc,
                       double* out, std::size_t out_stride);

}  // namespace nimbus::lpm
