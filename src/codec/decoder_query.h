// Answering decoder queries from CSV text: what `nbtf query --batch` does, kept in the
// library so it is tested directly.
//
// Input: one query per line, `x,y,theta_l,phi_l,theta_v,phi_v` (texel column and row of
// the material, light and view angles in degrees; spaces around fields are allowed).
// Blank lines and lines starting with '#' are skipped. A header is optional: when the first
// other line starts with a letter (e.g. "x,y,theta_l,..."), it is skipped. CRLF line ends
// are accepted. Angles: 0 <= theta <= 90, any finite phi.
//
// Output: a header, then per answered query its six fields as given, then the RGB:
// `x,y,theta_l,phi_l,theta_v,phi_v,r,g,b` (linear RGB, sRGB primaries, decoder output x
// alpha) or `...,r_norm,g_norm,b_norm` with --normalized (the decoder output itself).
// Values are printed with 9 significant digits (they read back as the same float).
// Malformed lines are reported on the error stream as "NAME:LINE: what is wrong" and
// skipped; the others are still answered. Lines are read and answered in batches
// (batchLines at a time, in parallel), so arbitrarily long inputs stream in bounded memory.
#pragma once
#include <cstddef>
#include <iosfwd>
#include <string>

#include "codec/decoder.h"

namespace nbtf {

struct QueryCsvOptions {
  OutputScale scale = OutputScale::Linear;
  std::size_t batchLines = 8192;  // lines read before answering; 1 = answer each line at once
};

struct QueryCsvStats {
  std::size_t lines = 0;      // lines read
  std::size_t answered = 0;   // queries answered
  std::size_t malformed = 0;  // lines reported as malformed
};

// Parses one data line (no line number in the message). Throws nbtf::Error.
TexelQuery parseQueryLine(const std::string& line, const NbtfDecoder& decoder);

QueryCsvStats answerQueryCsv(const NbtfDecoder& decoder, std::istream& in, const std::string& name,
                             std::ostream& out, std::ostream& errors, const QueryCsvOptions& options = {});

// "R G B" as printed by `nbtf query` for a single query (9 significant digits).
std::string formatRgb(const Rgb& rgb);

}  // namespace nbtf
