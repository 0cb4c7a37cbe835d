#include "io/btf_names.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <regex>

#include "util/error.h"

namespace nbtf {
namespace {
// Angles are integers in every known data set; decimals are accepted for shifted angles.
const std::regex& tokenRegex(int which) {
  static const std::regex tokens[4] = {
      std::regex(R"((?:^|[^A-Za-z])tl(\d+(?:\.\d+)?))"), std::regex(R"((?:^|[^A-Za-z])pl(\d+(?:\.\d+)?))"),
      std::regex(R"((?:^|[^A-Za-z])tv(\d+(?:\.\d+)?))"), std::regex(R"((?:^|[^A-Za-z])pv(\d+(?:\.\d+)?))")};
  return tokens[which];
}

std::string formatAngle(double deg) {
  char buf[32];
  if (std::fabs(deg - std::round(deg)) < 1e-9)
    std::snprintf(buf, sizeof buf, "%03d", static_cast<int>(std::lround(deg)));
  else
    std::snprintf(buf, sizeof buf, "%07.3f", deg);
  return buf;
}
}  // namespace

std::optional<ParsedBtfName> parseBtfFileName(const std::string& fileName) {
  std::string stem = fileName;
  auto dot = stem.rfind('.');
  if (dot != std::string::npos) stem = stem.substr(0, dot);
  double values[4];
  int found = 0;
  const char* names[4] = {"tl", "pl", "tv", "pv"};
  std::string missing;
  std::smatch m;
  for (int i = 0; i < 4; ++i) {
    if (std::regex_search(stem, m, tokenRegex(i))) {
      values[i] = std::stod(m[1].str());
      ++found;
    } else {
      missing += std::string(missing.empty() ? "" : ", ") + names[i];
    }
  }
  if (found == 0) return std::nullopt;
  if (found < 4) throw fileError(fileName, "file name does not parse: missing angle token(s) " + missing);
  ParsedBtfName p;
  p.light = {values[0], values[1]};
  p.view = {values[2], values[3]};
  for (int i : {0, 2})
    if (values[i] > 90) throw fileError(fileName, std::string("file name has ") + names[i] + " = " +
                                                      std::to_string(values[i]) + ", beyond the horizon (max 90)");
  for (int i : {1, 3})
    if (values[i] >= 360) throw fileError(fileName, std::string("file name has ") + names[i] + " = " +
                                                        std::to_string(values[i]) + " (azimuth must be < 360)");
  // UBO2003 names carry a running index: a standalone run of 4+ digits before the tokens.
  static const std::regex indexRegex(R"((?:^|[ _])(\d{4,})(?=[ _]))");
  if (std::regex_search(stem, m, indexRegex)) {
    p.index = std::stoi(m[1].str());
    p.layout = Layout::Ubo2003;
  } else {
    p.layout = Layout::Utia;
  }
  return p;
}

std::string viewFolderName(const Direction& view) {
  return "tv" + formatAngle(view.thetaDeg) + "_pv" + formatAngle(view.phiDeg);
}

std::string ubo2003FileName(int index, const Direction& light, const Direction& view, const std::string& ext) {
  char idx[16];
  std::snprintf(idx, sizeof idx, "%05d", index);
  return std::string(idx) + " tl" + formatAngle(light.thetaDeg) + " pl" + formatAngle(light.phiDeg) + " tv" +
         formatAngle(view.thetaDeg) + " pv" + formatAngle(view.phiDeg) + ext;
}

std::string utiaFileName(const Direction& light, const Direction& view, const std::string& ext) {
  return "tl" + formatAngle(light.thetaDeg) + "_pl" + formatAngle(light.phiDeg) + "_tv" + formatAngle(view.thetaDeg) +
         "_pv" + formatAngle(view.phiDeg) + ext;
}

bool isImageFileName(const std::string& name) {
  if (name.empty() || name[0] == '.') return false;
  const auto dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string ext = name.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".exr";
}

bool isViewFolderName(const std::string& name) {
  static const std::regex re(R"(.*tv\d+(\.\d+)?_pv\d+(\.\d+)?.*)");
  return std::regex_match(name, re);
}

}  // namespace nbtf
