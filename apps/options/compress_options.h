// The options of `nbtf compress`, declared and read in one place: the command line
// (apps/cmd_compress.cpp) and the Python module's nbtf.compress (python/) parse the same
// option set into the same CompressOptions, so the two cannot drift apart in names,
// defaults, checks or messages.
#pragma once
#include <cxxopts.hpp>
#include <string>

#include "pipeline/compressor.h"

namespace nbtf::cli {

// The command's own options and the input stack's (--crop, --layout); the common ones
// (--threads, -q) are added by parseCommand.
void addCompressOptions(cxxopts::Options& options);

struct CompressRequest {
  std::string input, output;
  std::string statsPath;   // --stats-json ("" = none)
  std::string configPath;  // --config as given ("" = none)
  CompressOptions options;
};

// The parsed options (after parseCommand, which applied --threads) as a request: the config
// loaded, the command line applied over it, every value checked (nbtf::Error naming the
// option). `program` prefixes warnings ("nbtf compress").
CompressRequest compressRequest(const cxxopts::ParseResult& args, const std::string& program);

// Before anything is read: no output may be an input or another output; the folders above
// the outputs are created and --stats-json is checked writable.
void prepareCompressOutputs(const CompressRequest& request);

}  // namespace nbtf::cli
