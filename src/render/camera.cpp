#include "render/camera.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "util/error.h"

namespace nbtf {

CameraSpec parseCamera(const std::string& text, const CameraSpec& base, const std::string& option) {
  std::vector<double> values;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::istringstream one(item);
    double v = 0;
    if (!(one >> v) || !(one >> std::ws).eof() || !std::isfinite(v))
      throw Error(option + ": '" + item + "' is not a number (expected EX,EY,EZ[,TX,TY,TZ[,FOV]], got '" + text + "')");
    values.push_back(v);
  }
  if (values.size() != 3 && values.size() != 6 && values.size() != 7)
    throw Error(option + ": expected 3, 6 or 7 numbers EX,EY,EZ[,TX,TY,TZ[,FOV]], got " +
                std::to_string(values.size()) + " in '" + text + "'");
  CameraSpec c = base;
  c.eye = {values[0], values[1], values[2]};
  if (values.size() >= 6) c.target = {values[3], values[4], values[5]};
  if (values.size() == 7) c.fovDeg = values[6];
  if (!(c.fovDeg > 0 && c.fovDeg < 170)) throw Error(option + ": field of view must be in (0, 170) degrees, got " + std::to_string(c.fovDeg));
  Vec3d f = c.target - c.eye;
  if (length(f) < 1e-9) throw Error(option + ": the eye and the target are the same point");
  Vec3d fn = normalize(f);
  if (std::fabs(fn.y) > 0.999) throw Error(option + ": the camera looks straight up or down (the image's up is +y)");
  return c;
}

Camera::Camera(const CameraSpec& spec, int width, int height) : spec_(spec), width_(width), height_(height) {
  if (width < 1 || height < 1) throw Error("image size must be at least 1x1");
  tanHalf_ = std::tan(spec.fovDeg * M_PI / 360.0);
  aspect_ = static_cast<double>(width) / height;
  forward_ = normalize(spec.target - spec.eye);
  right_ = normalize(cross(forward_, Vec3d(0, 1, 0)));
  up_ = cross(right_, forward_);
}

}  // namespace nbtf
