#include "src/core/anderson.h"

#include <algorithm>
#include <cmath>

#include "src/core/error.h"

namespace nimbus {
namespace {

// Solves (A + reg I) y = b for a symmetric positive semi-definite n x n A (row-major) by
// Cholesky; false when a pivot falls below `tiny` times the largest diagonal (ill-conditioned).
bool cholesky_solve(std::vector<double> A, std::vector<double> b, int n, std::vector<double>& y) {
    double dmax = 0.0;
    for (int i = 0; i < n; ++i) dmax = std::max(dmax, A[i * n + i]);
    if (!(dmax > 0.0)) return false;
    const double reg = 1e-14 * dmax, tiny = 1e-10 * dmax;
    for (int i = 0; i < n; ++i) A[i * n + i] += reg;
    for (int j = 0; j < n; ++j) {  // A = L L^T, L in the lower triangle
        double d = A[j * n + j];
        for (int k = 0; k < j; ++k) d -= A[j * n + k] * A[j * n + k];
        if (!(d > tiny)) return false;
        const double l = std::sqrt(d);
        A[j * n + j] = l;
        for (int i = j + 1; i < n; ++i) {
            double s = A[i * n + j];
            for (int k = 0; k < j; ++k) s -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = s / l;
        }
    }
    for (int i = 0; i < n; ++i) {  // L z = b
        for (int k = 0; k < i; ++k) b[i] -= A[i * n + k] * b[k];
        b[i] /= A[i * n + i];
    }
    for (int i = n - 1; i >= 0; --i) {  // L^T y = z
        for (int k = i + 1; k < n; ++k) b[i] -= A[k * n + i] * b[k];
        b[i] /= A[i * n + i];
    }
    y = std::move(b);
    return true;
}

}  // namespace

AndersonMixer::AndersonMixer(MPI_Comm comm, int depth, double beta) : comm_(comm), depth_(depth), beta_(beta) {
    if (depth < 0 || depth > 8) throw Error("Anderson acceleration: the depth must be in [0, 8]");
    if (!(beta > 0.0 && beta <= 1.0)) throw Error("Anderson acceleration: the mixing must be in (0, 1]");
}

void AndersonMixer::set_mixing(double beta) {
    if (!(beta > 0.0 && beta <= 1.0)) throw Error("Anderson acceleration: the mixing must be in (0, 1]");
    beta_ = beta;
}

std::vector<double> AndersonMixer::next(const std::vector<double>& x, const std::vector<double>& g) {
    if (x.size() != g.size() || (started_ && x.size() != x_prev_.size()))
        throw Error("Anderson acceleration: the vector changed length between iterations");
    const size_t n = x.size();
    std::vector<double> f(n);
    for (size_t i = 0; i < n; ++i) f[i] = g[i] - x[i];

    // started_, not !x_prev_.empty(): a rank whose share is empty (no cell of the medium) must
    // keep the same history length as the others, or the reduction below mismatches
    // (MPI_ERR_TRUNCATE with the flux limiter on 3 ranks, a review finding).
    if (started_ && depth_ > 0) {
        std::vector<double> dx(n), df(n);
        for (size_t i = 0; i < n; ++i) {
            dx[i] = x[i] - x_prev_[i];
            df[i] = f[i] - f_prev_[i];
        }
        dX_.push_back(std::move(dx));
        dF_.push_back(std::move(df));
        if (static_cast<int>(dF_.size()) > depth_) {
            dX_.pop_front();
            dF_.pop_front();
        }
    }
    // One reduction: the Gram matrix of dF (upper triangle), dF^T f and |f|^2.
    const int m = static_cast<int>(dF_.size());
    std::vector<double> sums(static_cast<size_t>(m * (m + 1) / 2 + m + 1), 0.0);
    {
        size_t s = 0;
        for (int a = 0; a < m; ++a)
            for (int b = a; b < m; ++b, ++s)
                for (size_t i = 0; i < n; ++i) sums[s] += dF_[a][i] * dF_[b][i];
        for (int a = 0; a < m; ++a, ++s)
            for (size_t i = 0; i < n; ++i) sums[s] += dF_[a][i] * f[i];
        for (size_t i = 0; i < n; ++i) sums[s] += f[i] * f[i];
    }
    MPI_Allreduce(MPI_IN_PLACE, sums.data(), static_cast<int>(sums.size()), MPI_DOUBLE, MPI_SUM, comm_);
    const double f_norm2 = sums.back();

    // Restart when the residual grew tenfold: the history describes another regime.
    const bool restart = m > 0 && f_norm2 > 100.0 * f_prev_norm2_;
    int first = restart ? m : 0;
    restarts_ += restart ? 1 : 0;
    // The newest columns that give a well-conditioned least-squares problem.
    std::vector<double> gamma;
    for (; first < m; ++first) {
        const int k = m - first;
        std::vector<double> A(static_cast<size_t>(k * k)), b(static_cast<size_t>(k));
        size_t s = 0;
        for (int a = 0; a < m; ++a)
            for (int c = a; c < m; ++c, ++s)
                if (a >= first && c >= first) {
                    A[(a - first) * k + (c - first)] = sums[s];
                    A[(c - first) * k + (a - first)] = sums[s];
                }
        for (int a = 0; a < m; ++a, ++s)
            if (a >= first) b[a - first] = sums[s];
        if (cholesky_solve(std::move(A), std::move(b), k, gamma)) break;
    }
    used_ = m - first;

    std::vector<double> out(n);
    for (size_t i = 0; i < n; ++i) out[i] = x[i] + beta_ * f[i];
    for (int a = 0; a < used_; ++a) {
        const double ga = gamma[static_cast<size_t>(a)];
        const auto& dx = dX_[static_cast<size_t>(first + a)];
        const auto& df = dF_[static_cast<size_t>(first + a)];
        for (size_t i = 0; i < n; ++i) out[i] -= ga * (dx[i] + beta_ * df[i]);
    }
    if (restart) {
        dX_.clear();
        dF_.clear();
    }
    x_prev_ = x;
    f_prev_ = std::move(f);
    started_ = true;
    f_prev_norm2_ = f_norm2;
    return out;
}

}  // namespace nimbus
