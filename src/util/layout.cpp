#include "util/layout.h"

#include <sstream>

#include "util/error.h"

namespace nbtf {

std::string sampleTypeName(SampleType t) { return t == SampleType::Srgb8 ? "8-bit sRGB" : "half float (linear)"; }

std::string layoutName(Layout l) {
  switch (l) {
    case Layout::Ubo2003: return "ubo2003";
    case Layout::Utia: return "utia";
    case Layout::Ubo2014: return "ubo2014";
    default: return "unknown";
  }
}

Layout parseLayout(const std::string& text) {
  if (text == "ubo2003" || text == "ubo") return Layout::Ubo2003;
  if (text == "utia") return Layout::Utia;
  if (text == "ubo2014") return Layout::Ubo2014;
  throw Error("unknown layout '" + text + "' (expected ubo2003, utia or ubo2014)");
}

Crop parseCrop(const std::string& text) {
  Crop c;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> c.x >> c1 >> c.y >> c2 >> c.width >> c3 >> c.height) || c1 != ',' || c2 != ',' || c3 != ',' ||
      !(in >> std::ws).eof())
    throw Error("--crop: expected X,Y,W,H (integers), got '" + text + "'");
  if (c.x < 0 || c.y < 0 || c.width <= 0 || c.height <= 0)
    throw Error("--crop: '" + text + "' must have X,Y >= 0 and W,H > 0");
  return c;
}

}  // namespace nbtf
