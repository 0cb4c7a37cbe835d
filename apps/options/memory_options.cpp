#include "options/memory_options.h"

#include <cerrno>
#include <filesystem>

#include "util/error.h"
#include "util/memory.h"

namespace nbtf::cli {

void addMemoryOptions(cxxopts::Options& options) {
  options.add_options("Memory")(
      "memory-limit",
      "Refuse, before loading, a run whose estimated peak memory is above SIZE (16G, 800M, bytes; default: 75% of "
      "physical memory)",
      cxxopts::value<std::string>())(
      "stack-storage",
      "Where an image stack's samples live: auto (a scratch file when the run would not fit in --memory-limit "
      "with them in memory), memory, or file",
      cxxopts::value<std::string>()->default_value("auto"))(
      "scratch-dir", "Folder of the stack's scratch file (default: the output's folder); a folder on disk",
      cxxopts::value<std::string>());
}

MemoryOptions memoryOptions(const cxxopts::ParseResult& args) {
  MemoryOptions m;
  if (args.count("memory-limit")) {
    const std::string limit = args["memory-limit"].as<std::string>();
    m.limit = parseByteSize(limit, "--memory-limit");
    m.limitText = "--memory-limit " + limit;
  }
  const std::string storage = args["stack-storage"].as<std::string>();
  if (storage == "auto")
    m.stack.storage = StackStorage::Auto;
  else if (storage == "memory")
    m.stack.storage = StackStorage::Memory;
  else if (storage == "file")
    m.stack.storage = StackStorage::File;
  else
    throw Error("--stack-storage must be auto, memory or file, got \"" + storage + "\"");
  if (args.count("scratch-dir")) {
    m.stack.scratchDir = args["scratch-dir"].as<std::string>();
    std::error_code ec;
    if (!std::filesystem::is_directory(m.stack.scratchDir, ec))
      throw fileAccessError(m.stack.scratchDir, "--scratch-dir: not a folder", ec ? ec.value() : ENOTDIR);
  }
  return m;
}

}  // namespace nbtf::cli
