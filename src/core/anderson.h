// Anderson acceleration of a fixed-point iteration x = G(x) over a vector split across ranks
// (Walker & Ni 2011, "Anderson acceleration for fixed-point iterations", SIAM J. Numer. Anal.
// 49(4), their Algorithm AA with mixing beta). With residuals f_k = G(x_k) - x_k and the last m
// differences  dF = [f_{i+1} - f_i],  dX = [x_{i+1} - x_i],
//   gamma    = argmin || f_k - dF gamma ||_2          (global dot products: one MPI_Allreduce)
//   x_{k+1}  = x_k + beta f_k - (dX + beta dF) gamma.
// m = 0 is the damped iteration x_{k+1} = x_k + beta f_k. The least-squares problem is solved
// by its normal equations (m <= 8, Tikhonov-regularized, columns dropped oldest first while the
// Gram matrix is ill-conditioned); the history restarts when the residual grows tenfold.
#pragma once

#include <mpi.h>

#include <deque>
#include <vector>

namespace nimbus {

class AndersonMixer {
public:
    // comm: the ranks sharing the vector (each holds its own part, of any length, fixed over
    // the iteration). depth m in [0, 8], mixing beta in (0, 1].
    AndersonMixer(MPI_Comm comm, int depth, double beta);

    // Given x_k and g = G(x_k) (this rank's parts, same length), returns x_{k+1}. Collective.
    std::vector<double> next(const std::vector<double>& x, const std::vector<double>& g);

    // The mixing of the following steps, in (0, 1].
    void set_mixing(double beta);

    // Columns used in the last step (0 while the history is empty or after a restart).
    int columns_used() const { return used_; }
    int restarts() const { return restarts_; }

private:
    MPI_Comm comm_;
    int depth_;
    double beta_;
    std::vector<double> x_prev_, f_prev_;
    bool started_ = false;  // next() has run: x_prev_ and f_prev_ hold the last iterate
    double f_prev_norm2_ = 0.0;
    std::deque<std::vector<double>> dX_, dF_;  // oldest first
    int used_ = 0;
    int restarts_ = 0;
};

}  // namespace nimbus
