// Error metrics between two runs (`nimbus compare`, jobs/study.py). Pure functions over dense
// arrays; B is the reference. Not collective, no I/O.
//
//   relative L2       ||a - b||_2 / ||b||_2             over cells with density > 0
//   max relative      max |a - b| / max |b|             over the same cells
//   RMS z             sqrt(mean((a - b)² / s²))         where the reference has a standard
//                                                       error s_b (Monte Carlo); s² = s_b², plus
//                                                       s_a² when A has one too (two Monte Carlo
//                                                       runs): ≈ 1 when a and b agree within
//                                                       their noise. Only cells where every
//                                                       given s is below kZRelStderr times its
//                                                       value count (z_cells): a cell no path
//                                                       reached has s = 0, and one that a few
//                                                       batches reached has s ≈ its value, an
//                                                       estimate so rough that its z ran to 367
//   sum ratio         Σ a / Σ b                         over the same cells: the totals' ratio
//                                                       (equal cells: total power), the bias that
//                                                       the L2 error mixes with the pattern's
//   image RMSE        sqrt(mean over pixels and RGB of (a - b)²), relative: ||a - b|| / ||b||;
//                     mean ratio Σ a / Σ b over pixels and RGB (brightness)
//   same medium       max |rho_a - rho_b| / max |rho_b| over all cells <= kSameMediumTolerance
//
// A metric whose denominator is zero is undefined, not infinite: it is NaN (`nimbus compare`
// prints "undefined" and writes JSON null) and `undefined` says why. Where a = b on every cell
// compared the fields agree exactly and every metric is 0, also over a zero reference.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace nimbus {

struct FieldError {
    double rel_l2 = 0.0;        // NaN when undefined
    double max_rel = 0.0;       // NaN when undefined
    double rms_z = -1.0;        // -1 when no standard error was given; NaN when undefined
    std::size_t cells = 0;      // cells compared (density > 0)
    std::size_t z_cells = 0;    // of those, the cells in rms_z (kZRelStderr; 0 without a standard error)
    double norm_b = 0.0;        // ||b||_2 over those cells
    double abs_l2 = 0.0;        // ||a - b||_2 over those cells (the field's units)
    double max_abs = 0.0;       // max |a - b| over those cells
    double sum_ratio = 0.0;     // Σ a / Σ b over those cells; NaN when Σ b = 0 (unless a = b)
    std::string undefined;      // empty, or why the NaN metrics are undefined
};

// a, b: one value per cell; density selects the cells (> 0); stderr_b may be null or hold one
// value per cell. Throws Error if the sizes differ. Undefined metrics (unless a = b on every
// cell compared): all of them without cells with density ("no cells with density"); rel_l2,
// max_rel (and rms_z if no cell has s_b > 0) when b is 0 on every cell compared ("the reference
// is zero on every cell compared"); rms_z alone when no cell passes kZRelStderr ("no cell
// compared has a usable standard error").
// stderr_a (may be null): A's own standard error, when A is a Monte Carlo run too.
FieldError field_error(const std::vector<double>& a, const std::vector<double>& b,
                       const std::vector<double>& density, const std::vector<double>* stderr_b,
                       const std::vector<double>* stderr_a = nullptr);

// RMS z takes a cell only where each run's standard error is below this fraction of its value.
// A batch mean reached by k of the batches has a relative standard error of about 1/sqrt(k), so
// 0.5 leaves out cells that 4 or fewer batches reached (MCNP's guideline calls a tally with a
// relative error above 0.5 "garbage"). Two smoke runs of 2 x 10^5 photons gave RMS z 3.9-5.1
// over every cell with s > 0 (the worst cell's z was 367), 1.0 with this cut and s_a counted.
inline constexpr double kZRelStderr = 0.5;

// max |a - b| / max |b| over all cells: 0 when a = b, +inf when b is all zero and a is not.
// Throws Error if the sizes differ.
double max_rel_difference(const std::vector<double>& a, const std::vector<double>& b);

// Two runs whose densities differ by more than this (relative, max_rel_difference) were runs of
// different media: beyond the round-off of the float32 output, which is the same for both.
inline constexpr double kSameMediumTolerance = 1e-6;

struct ImageError {
    double rmse = 0.0;
    double rel_error = 0.0;   // NaN when undefined
    double mean_ratio = 0.0;  // Σ a / Σ b over pixels and RGB; NaN when b is black (unless a = b)
    std::size_t pixels = 0;
    std::string undefined;  // empty, or why rel_error is undefined
};

// a, b: RGBA float images of the same size (alpha ignored). Throws Error if the sizes differ.
// rel_error is undefined when b is black and a is not ("the reference image is black").
ImageError image_error(const std::vector<float>& a_rgba, const std::vector<float>& b_rgba);

}  // namespace nimbus
