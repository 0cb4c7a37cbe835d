#include "pipeline/decode_selection.h"

#include <cmath>
#include <set>
#include <sstream>
#include <string>

#include "util/error.h"

namespace nbtf {

namespace {

double normalizedPhi(double phi) {
  double p = std::fmod(phi, 360.0);
  if (p < 0) p += 360.0;
  return p;
}

// To the 1e-6 degrees of a typed angle (tTHETApPHI), by the angles themselves.
bool sameAngles(const Direction& a, const Direction& b) {
  constexpr double kTol = 1e-6;
  if (std::fabs(a.thetaDeg - b.thetaDeg) > kTol) return false;
  if (a.thetaDeg <= kTol) return true;  // the pole: every azimuth is the same direction
  double d = std::fabs(normalizedPhi(a.phiDeg) - normalizedPhi(b.phiDeg));
  return std::min(d, 360.0 - d) <= kTol;
}

bool parseInt(const std::string& s, long& out) {
  if (s.empty() || !(std::isdigit(static_cast<unsigned char>(s[0])))) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtol(s.c_str(), &end, 10);
  return errno == 0 && *end == '\0';
}

bool parseDouble(const std::string& s, double& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  out = std::strtod(s.c_str(), &end);
  return *end == '\0' && std::isfinite(out);
}

}  // namespace

DirectionChoice chooseDirection(const Direction& d, const std::vector<Direction>& measured) {
  DirectionChoice c;
  c.direction = {d.thetaDeg, normalizedPhi(d.phiDeg)};
  for (std::size_t i = 0; i < measured.size(); ++i)
    if (sameAngles(c.direction, measured[i])) {
      c.direction = measured[i];
      c.index = static_cast<int>(i);
      break;
    }
  return c;
}

std::vector<DirectionChoice> allDirections(const std::vector<Direction>& measured) {
  std::vector<DirectionChoice> out;
  for (std::size_t i = 0; i < measured.size(); ++i) out.push_back({measured[i], static_cast<int>(i)});
  return out;
}

std::vector<DirectionChoice> parseDirectionList(const std::string& text, const std::vector<Direction>& measured,
                                                const std::string& option) {
  const std::string what = option.substr(option.find_first_not_of('-')) == "views" ? "view" : "light";
  if (text == "all") return allDirections(measured);
  auto fail = [&](const std::string& item, const std::string& why) {
    return Error(option + ": item '" + item + "' " + why +
                 " (LIST: 'all', or comma-separated N, N-M or tTHETApPHI, e.g. '0-5,12,t37.5p200')");
  };
  const int count = static_cast<int>(measured.size());
  std::vector<DirectionChoice> out;
  auto add = [&](const DirectionChoice& c) {
    for (const auto& e : out)
      if (c.measured() ? e.index == c.index : (!e.measured() && sameAngles(e.direction, c.direction))) return;
    out.push_back(c);
  };
  std::string item;
  std::istringstream in(text);
  bool any = false;
  while (std::getline(in, item, ',')) {
    any = true;
    if (item.empty()) throw fail(item, "is empty");
    if (item[0] == 't') {
      auto p = item.find('p');
      double theta = 0, phi = 0;
      if (p == std::string::npos || !parseDouble(item.substr(1, p - 1), theta) || !parseDouble(item.substr(p + 1), phi))
        throw fail(item, "is not tTHETApPHI with THETA and PHI in degrees");
      Direction d{theta, phi};
      try {
        checkHemisphere(d, what);
      } catch (const Error& e) {
        throw fail(item, std::string("is not on the hemisphere: ") + e.what());
      }
      add(chooseDirection(d, measured));
      continue;
    }
    long first = 0, last = 0;
    auto dash = item.find('-');
    bool ok = dash == std::string::npos ? parseInt(item, first) && (last = first, true)
                                        : parseInt(item.substr(0, dash), first) && parseInt(item.substr(dash + 1), last);
    if (!ok) throw fail(item, "is not an index N, a range N-M or tTHETApPHI");
    if (first > last) throw fail(item, "is an empty range (N-M needs N <= M)");
    if (last >= count)
      throw fail(item, "is out of range: the material has " + std::to_string(count) + " " + what + " directions (0.." +
                           std::to_string(count - 1) + ")");
    for (long i = first; i <= last; ++i) add({measured[i], static_cast<int>(i)});
  }
  if (!any) throw fail(text, "is empty");
  return out;
}

std::pair<int, int> parseImageSize(const std::string& text, const std::string& option, int maxSide) {
  long w = 0, h = 0;
  auto x = text.find_first_of("xX");
  if (x == std::string::npos || !parseInt(text.substr(0, x), w) || !parseInt(text.substr(x + 1), h))
    throw Error(option + ": expected WxH (e.g. 256x256), got '" + text + "'");
  const long kMax = maxSide;
  if (w < 1 || h < 1 || w > kMax || h > kMax)
    throw Error(option + ": size " + text + " is out of range (1 .. " + std::to_string(kMax) + " per side)");
  return {static_cast<int>(w), static_cast<int>(h)};
}

}  // namespace nbtf
