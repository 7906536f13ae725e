#include "solvers/lpm/gather_kernel.h"

#include <cstring>

namespace nimbus::lpm {
namespace {

// NC outputs known at compile time: the NC accumulators of a block of 4 cells stay in
// registers across the direction loop (NC <= 10 fits the 16 AVX registers).
// (always_inline: so that each target clone below gets its own vectorized copy.)
template <int NC>
__attribute__((always_inline)) inline void gather_fixed(int n, int nl, double* phi, std::size_t stride, const double* C, int cs, double* out,
                         std::size_t os) {
    int i = 0;
    // Four cells per GCC/Clang vector (one AVX register, two SSE2 ones in the default clone);
    // no helper functions take or return it, so the ABI does not depend on the clone.
    typedef double V4 __attribute__((vector_size(32)));
    const V4 zero{};
    for (; i + 4 <= n; i += 4) {
        V4 acc[NC];
        for (int k = 0; k < NC; ++k) acc[k] = V4{};
        for (int l = 0; l < nl; ++l) {
            double* ph = phi + static_cast<std::size_t>(l) * stride + i;
            V4 x;
            std::memcpy(&x, ph, sizeof x);
            std::memcpy(ph, &zero, sizeof zero);
            const double* c = C + static_cast<std::size_t>(l) * cs;
            for (int k = 0; k < NC; ++k) acc[k] += c[k] * x;
        }
        for (int k = 0; k < NC; ++k) {
            const V4 a = acc[k];  // (a copy: acc's address is never taken, so it stays in registers)
            std::memcpy(out + static_cast<std::size_t>(k) * os + i, &a, sizeof a);
        }
    }
    for (; i < n; ++i) {
        double acc[NC] = {};
        for (int l = 0; l < nl; ++l) {
            double& ph = phi[static_cast<std::size_t>(l) * stride + i];
            const double* c = C + static_cast<std::size_t>(l) * cs;
            for (int k = 0; k < NC; ++k) acc[k] += c[k] * ph;
            ph = 0.0;
        }
        for (int k = 0; k < NC; ++k) out[static_cast<std::size_t>(k) * os + i] = acc[k];
    }
}

// Any number of outputs (e.g. 54 coarse bins for k = 3): output-major passes over the rows.
__attribute__((always_inline)) inline void gather_any(int n, int nl, double* phi, std::size_t stride, const double* C, int cs, int nc,
                       double* out, std::size_t os) {
    for (int k = 0; k < nc; ++k) {
        double* o = out + static_cast<std::size_t>(k) * os;
        for (int i = 0; i < n; ++i) o[i] = 0.0;
        for (int l = 0; l < nl; ++l) {
            const double c = C[static_cast<std::size_t>(l) * cs + k];
            const double* ph = phi + static_cast<std::size_t>(l) * stride;
            for (int i = 0; i < n; ++i) o[i] += c * ph[i];
        }
    }
    for (int l = 0; l < nl; ++l) std::memset(phi + static_cast<std::size_t>(l) * stride, 0, sizeof(double) * n);
}

}  // namespace

__attribute__((target_clones("arch=x86-64-v3", "default"))) void gather_directions(int n, int nl, double* phi,
                                                                                    std::size_t stride,
                                                                                    const double* C, int c_stride,
                                                                                    int nc, double* out,
                                                                                    std::size_t out_stride) {
    switch (nc) {
        case 1: gather_fixed<1>(n, nl, phi, stride, C, c_stride, out, out_stride); break;
        case 4: gather_fixed<4>(n, nl, phi, stride, C, c_stride, out, out_stride); break;
        case 7: gather_fixed<7>(n, nl, phi, stride, C, c_stride, out, out_stride); break;
        case 10: gather_fixed<10>(n, nl, phi, stride, C, c_stride, out, out_stride); break;
        default: gather_any(n, nl, phi, stride, C, c_stride, nc, out, out_stride); break;
    }
}

}  // namespace nimbus::lpm
