#include "codec/decoder_query.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <istream>
#include <ostream>
#include <vector>

#include "util/error.h"

namespace nbtf {
namespace {

const char* const kFieldNames[6] = {"x", "y", "theta_l", "phi_l", "theta_v", "phi_v"};

std::string trim(const std::string& s) {
  std::size_t b = s.find_first_not_of(" \t"), e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

std::vector<std::string> splitFields(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  while (true) {
    std::size_t comma = line.find(',', start);
    fields.push_back(trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return fields;
}

std::string fieldLabel(int i) { return "field " + std::to_string(i + 1) + " (" + kFieldNames[i] + ")"; }

int parseIntField(const std::string& s, int i) {
  char* end = nullptr;
  errno = 0;
  long v = std::strtol(s.c_str(), &end, 10);
  if (s.empty() || *end != '\0' || errno != 0 || v < -(1L << 30) || v > (1L << 30))
    throw Error(fieldLabel(i) + " '" + s + "' is not an integer texel coordinate");
  return static_cast<int>(v);
}

double parseAngleField(const std::string& s, int i) {
  char* end = nullptr;
  double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0') throw Error(fieldLabel(i) + " '" + s + "' is not a number (degrees)");
  if (!std::isfinite(v)) throw Error(fieldLabel(i) + " '" + s + "' is not finite");
  return v;
}

bool isSkippable(const std::string& trimmed) { return trimmed.empty() || trimmed[0] == '#'; }

}  // namespace

TexelQuery parseQueryLine(const std::string& line, const NbtfDecoder& decoder) {
  std::vector<std::string> f = splitFields(line);
  if (f.size() != 6)
    throw Error("expected 6 comma-separated fields (x,y,theta_l,phi_l,theta_v,phi_v), got " + std::to_string(f.size()));
  TexelQuery q;
  q.x = parseIntField(f[0], 0);
  q.y = parseIntField(f[1], 1);
  q.light = {parseAngleField(f[2], 2), parseAngleField(f[3], 3)};
  q.view = {parseAngleField(f[4], 4), parseAngleField(f[5], 5)};
  decoder.checkTexel(q.x, q.y);
  checkHemisphere(q.light, "light");
  checkHemisphere(q.view, "view");
  return q;
}

std::string formatRgb(const Rgb& c) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g", c.r, c.g, c.b);
  return buf;
}

QueryCsvStats answerQueryCsv(const NbtfDecoder& decoder, std::istream& in, const std::string& name, std::ostream& out,
                             std::ostream& errors, const QueryCsvOptions& options) {
  QueryCsvStats stats;
  const std::size_t batch = std::max<std::size_t>(1, options.batchLines);
  out << "x,y,theta_l,phi_l,theta_v,phi_v,"
      << (options.scale == OutputScale::Linear ? "r,g,b" : "r_norm,g_norm,b_norm") << '\n';
  std::vector<TexelQuery> queries;
  std::vector<std::string> echoes;  // the six fields as given, for the output rows
  std::vector<float> rgb;
  auto answer = [&] {
    rgb.resize(3 * queries.size());
    decoder.evaluate(queries.data(), queries.size(), rgb.data(), options.scale);
    std::string text;
    char buf[96];
    for (std::size_t i = 0; i < queries.size(); ++i) {
      std::snprintf(buf, sizeof buf, ",%.9g,%.9g,%.9g\n", rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
      text += echoes[i];
      text += buf;
    }
    out << text;
    out.flush();
    stats.answered += queries.size();
    queries.clear();
    echoes.clear();
  };

  bool seenData = false;
  std::string line;
  while (std::getline(in, line)) {
    ++stats.lines;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::string t = trim(line);
    if (isSkippable(t)) continue;
    if (!seenData) {
      seenData = true;
      if (std::isalpha(static_cast<unsigned char>(t[0]))) continue;  // header
    }
    try {
      queries.push_back(parseQueryLine(t, decoder));
      std::vector<std::string> f = splitFields(t);
      echoes.push_back(f[0] + ',' + f[1] + ',' + f[2] + ',' + f[3] + ',' + f[4] + ',' + f[5]);
    } catch (const Error& e) {
      ++stats.malformed;
      errors << name << ':' << stats.lines << ": " << e.what() << '\n';
    }
    if (queries.size() >= batch) answer();
  }
  if (in.bad()) throw fileError(name, "read error");
  if (!queries.empty()) answer();
  errors.flush();
  return stats;
}

}  // namespace nbtf
