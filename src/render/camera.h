// A pinhole camera. Rays are generated as functions of the continuous image-plane
// position (px, py) in pixel units (pixel (i, j) covers [i, i+1) x [j, j+1), row 0 on
// top), so a ray over `Dual` carries d/dpx and d/dpy (the adaptive-oversampling paper, eq. 9-11).
#pragma once
#include <string>

#include "render/dual.h"

namespace nbtf {

template <class T>
struct Ray {
  Vec3<T> origin;
  Vec3<T> dir;  // unit length
};

struct CameraSpec {
  Vec3d eye{0, 2, 4};
  Vec3d target{0, 0.5, 0};
  double fovDeg = 40;  // vertical field of view
};
// "EX,EY,EZ[,TX,TY,TZ[,FOV]]" -> CameraSpec (unspecified parts keep `base`); throws
// nbtf::Error naming `option` on bad text.
CameraSpec parseCamera(const std::string& text, const CameraSpec& base, const std::string& option);

class Camera {
 public:
  Camera(const CameraSpec& spec, int width, int height);
  int width() const { return width_; }
  int height() const { return height_; }
  const CameraSpec& spec() const { return spec_; }

  template <class T>
  Ray<T> ray(const T& px, const T& py) const {
    const T sx = (px * (2.0 / width_) - 1.0) * (tanHalf_ * aspect_);
    const T sy = (1.0 - py * (2.0 / height_)) * tanHalf_;
    Vec3<T> d = Vec3<T>(forward_) + right_ * sx + up_ * sy;
    return {Vec3<T>(spec_.eye), normalize(d)};
  }
  // The ray through (px, py) with derivatives with respect to px and py.
  Ray<Dual> dualRay(double px, double py) const { return ray(Dual(px, 1, 0), Dual(py, 0, 1)); }

 private:
  CameraSpec spec_;
  int width_, height_;
  double tanHalf_, aspect_;
  Vec3d forward_, right_, up_;
};

}  // namespace nbtf
