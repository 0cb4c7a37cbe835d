#include "util/memory.h"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "util/error.h"

namespace nbtf {

std::size_t parseByteSize(const std::string& text, const std::string& option) {
  auto bad = [&](const std::string& why) {
    return Error(option + ": expected a size in bytes such as 16G, 800M or 1073741824, got '" + text + "' (" + why + ")");
  };
  std::size_t pos = 0;
  while (pos < text.size() && (std::isdigit(static_cast<unsigned char>(text[pos])) || text[pos] == '.')) ++pos;
  if (pos == 0) throw bad("no number");
  double value = 0;
  try {
    std::size_t used = 0;
    value = std::stod(text.substr(0, pos), &used);
    if (used != pos) throw bad("not a number");
  } catch (const std::logic_error&) {
    throw bad("not a number");
  }
  std::string unit = text.substr(pos);
  for (char& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();
  double scale = 1;
  if (unit.empty() || unit == "B") scale = 1;
  else if (unit == "K") scale = 1024.0;
  else if (unit == "M") scale = 1024.0 * 1024;
  else if (unit == "G") scale = 1024.0 * 1024 * 1024;
  else if (unit == "T") scale = 1024.0 * 1024 * 1024 * 1024;
  else throw bad("unknown unit '" + text.substr(pos) + "'; use K, M, G or T");
  const double bytes = value * scale;
  if (!std::isfinite(bytes) || bytes > 1e18) throw bad("too large: at most 1e18 bytes");
  if (!(bytes >= 1)) throw bad("must be at least 1 byte");
  return static_cast<std::size_t>(bytes);
}

void reuseFreedMemory() {
#if defined(__GLIBC__)
  // Setting either also stops glibc from moving the thresholds itself.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
}

std::size_t physicalMemoryBytes() {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("MemTotal:", 0) != 0) continue;
    std::istringstream s(line.substr(9));
    std::size_t kib = 0;
    if (s >> kib) return kib * 1024;
  }
  return 0;
}

std::size_t defaultMemoryLimit() {
  const std::size_t physical = physicalMemoryBytes();
  return physical > 0 ? physical / 4 * 3 : (std::size_t(8) << 30);
}

std::size_t peakResidentBytes() {
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
  return static_cast<std::size_t>(usage.ru_maxrss) * 1024;  // Linux: KiB
}

std::string formatBytes(std::size_t bytes) {
  char out[64];
  const double b = static_cast<double>(bytes);
  if (b >= 1024.0 * 1024 * 1024) std::snprintf(out, sizeof out, "%.2f GiB", b / (1024.0 * 1024 * 1024));
  else if (b >= 1024.0 * 1024) std::snprintf(out, sizeof out, "%.0f MiB", b / (1024.0 * 1024));
  else if (b >= 1024.0) std::snprintf(out, sizeof out, "%.0f KiB", b / 1024.0);
  else std::snprintf(out, sizeof out, "%.0f B", b);
  return out;
}

}  // namespace nbtf
