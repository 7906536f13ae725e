// A small 3-vector of doubles for geometry (directions, positions in metres).
#pragma once

#include <algorithm>
#include <cmath>

namespace nimbus {

struct Vec3 {
    double x = 0, y = 0, z = 0;

    double operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
    double& operator[](int a) { return a == 0 ? x : (a == 1 ? y : z); }
    Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
    Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
};

inline Vec3 operator*(double s, const Vec3& v) { return v * s; }
inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(const Vec3& v) { return std::sqrt(dot(v, v)); }
inline Vec3 normalized(const Vec3& v) { return v / norm(v); }
// The unit vector along v for any finite non-zero v: scaled by its largest component first, so
// that |v|² can neither underflow (1e-200) nor overflow (1e200). NaN components give NaN.
inline Vec3 normalized_any_scale(const Vec3& v) {
    const double m = std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    return normalized(v / m);
}

}  // namespace nimbus
