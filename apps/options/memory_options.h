// The memory options of the commands that load a whole stack (`compress`, `cluster`), declared
// and read once: --memory-limit, --stack-storage, --scratch-dir (docs/compress.md, *Memory*).
#pragma once
#include <cxxopts.hpp>
#include <cstddef>
#include <string>

#include "pipeline/memory_estimate.h"

namespace nbtf::cli {

void addMemoryOptions(cxxopts::Options& options);

struct MemoryOptions {
  std::size_t limit = 0;   // --memory-limit in bytes; 0 = not given (the default limit)
  std::string limitText;   // how the limit was given, for errors ("" = the default)
  StackStorageOptions stack;
};

// The parsed options, checked: a bad size or storage names its option; --scratch-dir must be a
// folder (nbtf::FileAccessError naming it).
MemoryOptions memoryOptions(const cxxopts::ParseResult& args);

}  // namespace nbtf::cli
