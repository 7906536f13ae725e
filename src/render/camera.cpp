#include "src/render/camera.h"

#include <cmath>
#include <numbers>

#include "src/core/error.h"

namespace nimbus {
namespace {

Vec3 to_world(const Vec3& v, const CameraSpec& spec, const Grid& grid) {
    if (!spec.domain_units) return v;
    const Vec3 e = grid.extent();
    return {grid.origin.x + v.x * e.x, grid.origin.y + v.y * e.y, grid.origin.z + v.z * e.z};
}

}  // namespace

Camera::Camera(const CameraSpec& spec, const Grid& grid)
    : position_(to_world(spec.position, spec, grid)),
      look_at_(to_world(spec.look_at, spec, grid)),
      width_(spec.width),
      height_(spec.height) {
    if (width_ <= 0 || height_ <= 0) throw Error("camera image size must be positive");
    if (!(spec.fov_deg > 0 && spec.fov_deg < 180))
        throw Error("camera.fov must be in (0, 180) degrees");
    const Vec3 view = look_at_ - position_;
    if (!(norm(view) > 0)) throw Error("camera.look_at equals camera.position: the camera looks at nothing");
    forward_ = normalized(view);
    const Vec3 side = cross(forward_, spec.up);
    if (!(norm(side) > 1e-9 * norm(spec.up))) throw Error("camera.up is parallel to the view direction");
    right_ = normalized(side);
    up_ = cross(right_, forward_);
    half_h_ = std::tan(0.5 * spec.fov_deg * std::numbers::pi / 180.0);
    half_w_ = half_h_ * static_cast<double>(width_) / height_;
}

}  // namespace nimbus
