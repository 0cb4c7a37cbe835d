// Small helpers shared by the subcommands: option parsing with clear errors, the
// --threads option, and running a body that may throw nbtf::Error.
#pragma once
#include <cxxopts.hpp>
#include <functional>
#include <iostream>
#include <string>

#include "util/error.h"
#include "util/parallel.h"

namespace nbtf::cli {

// Parses argv; on --help prints usage and returns false (exit 0); bad options throw nbtf::Error.
inline bool parseOptions(cxxopts::Options& options, int argc, char** argv, cxxopts::ParseResult& result) {
  try {
    result = options.parse(argc, argv);
  } catch (const std::exception& e) {
    throw Error(std::string(e.what()) + " (see '" + options.program() + " --help')");
  }
  if (result.count("help")) {
    std::cout << options.help() << std::endl;
    return false;
  }
  return true;
}

// Adds --threads and --help, the options every subcommand has.
inline void addCommonOptions(cxxopts::Options& options) {
  options.add_options("Common")("threads", "Worker threads (0 = all cores)", cxxopts::value<int>()->default_value("0"))(
      "h,help", "Show this help");
}

inline void applyCommonOptions(const cxxopts::ParseResult& result) {
  int threads = result["threads"].as<int>();
  if (threads < 0) throw Error("--threads must be >= 0, got " + std::to_string(threads));
  setThreadCount(threads);
}

// Runs the body; prints nbtf::Error and other exceptions as "nbtf <cmd>: error: ..." and returns 1.
inline int runGuarded(const std::string& command, const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::cerr << "nbtf " << command << ": error: " << e.what() << std::endl;
    return 1;
  }
}

}  // namespace nbtf::cli
