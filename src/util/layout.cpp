#include "util/layout.h"

#include <limits>
#include <sstream>
#include <vector>

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
  // Four comma-separated decimal integers, each read as a 64-bit value first so that one too
  // large for a crop is named as such (not as "not an integer").
  std::vector<long long> v;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::size_t first = item.find_first_not_of(" \t"), last = item.find_last_not_of(" \t");
    item = first == std::string::npos ? "" : item.substr(first, last - first + 1);
    const bool digits = !item.empty() && item.find_first_not_of("0123456789") == std::string::npos;
    const bool negative = item.size() > 1 && item[0] == '-' && item.find_first_not_of("0123456789", 1) == std::string::npos;
    if (!digits && !negative) throw Error("--crop: expected X,Y,W,H (integers), got '" + text + "'");
    if (item.size() > 18)
      throw Error("--crop: " + item + " in '" + text + "' is too large (at most " +
                  std::to_string(std::numeric_limits<int>::max()) + ")");
    v.push_back(std::stoll(item));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (v.size() != 4) throw Error("--crop: expected X,Y,W,H (integers), got '" + text + "'");
  for (long long value : v)
    if (value > std::numeric_limits<int>::max())
      throw Error("--crop: " + std::to_string(value) + " in '" + text + "' is too large (at most " +
                  std::to_string(std::numeric_limits<int>::max()) + ")");
  Crop c;
  c.x = static_cast<int>(v[0]), c.y = static_cast<int>(v[1]);
  c.width = static_cast<int>(v[2]), c.height = static_cast<int>(v[3]);
  if (c.x < 0 || c.y < 0 || c.width <= 0 || c.height <= 0)
    throw Error("--crop: '" + text + "' must have X,Y >= 0 and W,H > 0");
  return c;
}

}  // namespace nbtf
