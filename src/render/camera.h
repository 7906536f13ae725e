// Pinhole camera (render side of CameraSpec). Not collective; cheap to copy.
//
// World position p = origin + f ⊙ extent when spec.domain_units (f in fractions of the domain
// extent), else spec.position itself in metres; the same for look_at. Image plane at unit
// distance along forward = normalize(look_at - position), vertical field of view fov:
//   right = normalize(forward × up_spec),  up = right × forward,
//   d(u, v) = normalize(forward + (2u/W - 1) tan(fov/2) (W/H) right + (1 - 2v/H) tan(fov/2) up)
// for continuous image coordinates u in [0, W], v in [0, H], v = 0 the TOP edge; pixel (x, y)
// is sampled at its centre (x + 0.5, y + 0.5), so row y = 0 is the top row.
#pragma once

#include "src/core/grid.h"
#include "src/core/vec3.h"
#include "src/scene/scene.h"

namespace nimbus {

class Camera {
public:
    // Throws Error when the view is degenerate in world units (look_at == position, up parallel
    // to the view direction, non-positive image size, fov outside (0, 180) degrees).
    Camera(const CameraSpec& spec, const Grid& grid);

    const Vec3& position() const { return position_; }
    const Vec3& look_at() const { return look_at_; }
    const Vec3& forward() const { return forward_; }
    const Vec3& right() const { return right_; }
    const Vec3& up() const { return up_; }
    int width() const { return width_; }
    int height() const { return height_; }

    // Unit direction of the view ray through continuous image point (u, v).
    Vec3 direction(double u, double v) const {
        const double sx = (2.0 * u / width_ - 1.0) * half_w_, sy = (1.0 - 2.0 * v / height_) * half_h_;
        return normalized(forward_ + right_ * sx + up_ * sy);
    }
    // Unit direction of the view ray through the centre of pixel (x, y), y = 0 the top row.
    Vec3 pixel_direction(int x, int y) const { return direction(x + 0.5, y + 0.5); }
    // Continuous image coordinates (u, v) of world point p (the inverse of direction());
    // false when p is not strictly in front of the camera.
    bool project(const Vec3& p, double& u, double& v) const {
        const Vec3 r = p - position_;
        const double z = dot(r, forward_);
        if (!(z > 0)) return false;
        u = 0.5 * width_ * (1.0 + dot(r, right_) / (z * half_w_));
        v = 0.5 * height_ * (1.0 - dot(r, up_) / (z * half_h_));
        return true;
    }

private:
    Vec3 position_, look_at_, forward_, right_, up_;
    int width_ = 0, height_ = 0;
    double half_w_ = 0, half_h_ = 0;  // tan(fov/2) * aspect, tan(fov/2)
};

}  // namespace nimbus
