// Small helpers shared by the subcommands: option parsing with clear errors (naming the
// option, rejecting extra arguments), the options every command has (--threads, -q),
// output folders, and running a body that may throw nbtf::Error.
#pragma once
#include <unistd.h>

#include <cxxopts.hpp>
#include <filesystem>
#include <functional>
#include <optional>
#include <iostream>
#include <string>
#include <thread>

#include "codec/decoder.h"
#include "util/error.h"
#include "util/layout.h"
#include "util/path_guard.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf::cli {

// cxxopts reports a bad value as "Argument 'abc' failed to parse": find the option it was
// given to ("--clusters abc", "--clusters=abc", "-k abc").
inline std::string optionOfValue(int argc, char** argv, const std::string& message) {
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg.size() < 2 || arg[0] != '-') continue;
    std::string name = arg, value;
    auto eq = arg.find('=');
    if (eq != std::string::npos) name = arg.substr(0, eq), value = arg.substr(eq + 1);
    else if (i + 1 < argc) value = argv[i + 1];
    if (!value.empty() && message.find(cxxopts::LQUOTE + value + cxxopts::RQUOTE) != std::string::npos) return name;
  }
  return "";
}

// Parses argv; on --help prints usage and returns false (exit 0); bad options, bad values
// (naming the option) and extra positional arguments throw nbtf::Error.
inline bool parseOptions(cxxopts::Options& options, int argc, char** argv, cxxopts::ParseResult& result) {
  const std::string seeHelp = " (see '" + options.program() + " --help')";
  try {
    result = options.parse(argc, argv);
  } catch (const cxxopts::exceptions::incorrect_argument_type& e) {
    const std::string option = optionOfValue(argc, argv, e.what());
    if (option.empty()) throw Error(std::string(e.what()) + seeHelp);
    throw Error(option + ": invalid value: " + e.what() + seeHelp);
  } catch (const std::exception& e) {
    throw Error(std::string(e.what()) + seeHelp);
  }
  if (result.count("help")) {
    std::cout << options.help() << std::endl;
    return false;
  }
  if (!result.unmatched().empty()) {
    std::string extra;
    for (const auto& a : result.unmatched()) extra += (extra.empty() ? "'" : ", '") + a + "'";
    throw Error("unexpected argument" + std::string(result.unmatched().size() > 1 ? "s " : " ") + extra +
                ": this command takes one input" + seeHelp);
  }
  return true;
}

// Adds the options every subcommand has: --threads, -q / --quiet, --help.
inline void addCommonOptions(cxxopts::Options& options) {
  options.add_options("Common")("threads", "Worker threads (0 = all cores; more than the cores are capped)",
                                cxxopts::value<int>()->default_value("0"))(
      "q,quiet", "No progress bars (results, summaries, warnings and errors are still printed)")(
      "h,help", "Show this help");
}

// ---- Option groups: an option several commands take is declared and read here, once.

// --crop and --layout of an input image stack. `defaults` ends the help text, e.g.
// " (default: the file's)" where the command has a fallback.
inline void addCropOption(cxxopts::Options& options, const std::string& defaults = "") {
  options.add_options("Input stack")("crop", "Crop X,Y,W,H applied while loading" + defaults,
                                     cxxopts::value<std::string>());
}
inline void addLayoutOption(cxxopts::Options& options, const std::string& defaults = " (default: detected)") {
  options.add_options("Input stack")("layout", "Force the layout: ubo2003 or utia" + defaults,
                                     cxxopts::value<std::string>());
}
inline void addStackOptions(cxxopts::Options& options) {
  addCropOption(options);
  addLayoutOption(options);
}
inline std::optional<Crop> cropOption(const cxxopts::ParseResult& args) {
  if (!args.count("crop")) return std::nullopt;
  return parseCrop(args["crop"].as<std::string>());
}
inline std::optional<Layout> layoutOption(const cxxopts::ParseResult& args) {
  if (!args.count("layout")) return std::nullopt;
  return parseLayout(args["layout"].as<std::string>());
}

// --isa: the decoder's kernels.
inline void addDecoderIsaOption(cxxopts::Options& options) {
  options.add_options("Decoder")("isa", "Decoder kernels: auto, portable, avx2, avx512",
                                 cxxopts::value<std::string>()->default_value("auto"));
}
inline DecoderIsa decoderIsaOption(const cxxopts::ParseResult& args) {
  return parseDecoderIsa(args["isa"].as<std::string>());
}

inline void applyCommonOptions(const cxxopts::ParseResult& result, const std::string& program);

// The end of every command's option set-up: the common options, the positional argument,
// parsing, and the common options applied. False: --help was printed (exit 0).
inline bool parseCommand(cxxopts::Options& options, const std::string& positional, int argc, char** argv,
                         cxxopts::ParseResult& args) {
  addCommonOptions(options);
  options.parse_positional({positional});
  if (!parseOptions(options, argc, argv, args)) return false;
  applyCommonOptions(args, options.program());
  return true;
}

// More threads than cores only slow the work down (each stage splits its work per thread
// and waits for the slowest): cap with a warning. One rule wherever a thread count comes from:
// `--threads` (what = "--threads") or a config file's training.threads (what names the key and
// the file).
inline int cappedThreads(int threads, const std::string& program, const std::string& what = "--threads") {
  if (threads < 0) throw Error(what + " must be >= 0, got " + std::to_string(threads));
  const int cores = static_cast<int>(std::thread::hardware_concurrency());
  if (cores > 0 && threads > cores) {
    std::cerr << program << ": warning: " << what << " " << threads << " is more than the " << cores
              << " cores of this machine; using " << cores << std::endl;
    return cores;
  }
  return threads;
}

inline void applyCommonOptions(const cxxopts::ParseResult& result, const std::string& program) {
  setThreadCount(cappedThreads(result["threads"].as<int>(), program));
  if (result.count("quiet")) Progress::setQuiet(true);
}

// An output folder that will be created (with its parents) when the results are written:
// checked now, created only then, so a failed run leaves no empty folder behind.
inline void checkFolderCreatable(const std::string& folder) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path p = fs::absolute(folder, ec);
  if (fs::exists(p, ec) && !fs::is_directory(p, ec)) throw fileError(folder, "exists and is not a folder");
  while (!p.empty() && !fs::exists(p, ec) && p != p.parent_path()) p = p.parent_path();
  if (!fs::is_directory(p, ec))
    throw fileError(folder, "cannot be created: '" + p.string() + "' is not a folder");
  if (::access(p.c_str(), W_OK) != 0)
    throw fileError(folder, "cannot be created: the folder '" + p.string() + "' is not writable");
}

// Creates the output folder (and its parents) that checkFolderCreatable accepted.
inline void createFolder(const std::string& folder) {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec) throw fileError(folder, "cannot create the folder: " + ec.message());
}

inline bool isFolder(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_directory(path, ec);
}

inline bool quiet(const cxxopts::ParseResult& result) { return result.count("quiet") > 0; }

// Runs the body; prints nbtf::Error and other exceptions as "nbtf <cmd>: error: ..." and returns 1.
inline int runGuarded(const std::string& command, const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::cerr << "nbtf " << command << ": error: " << userMessage(e) << std::endl;
    return 1;
  }
}

}  // namespace nbtf::cli
