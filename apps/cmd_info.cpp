// nbtf info <path>: describe a BTF image stack folder or a compressed .nbtf file.
#include <cstdio>
#include <filesystem>

#include "cli_common.h"
#include "codec/nbtf_describe.h"
#include "codec/nbtf_file.h"
#include "commands.h"
#include "io/btf_loader.h"
#include "util/atomic_file.h"
#include "util/progress.h"

namespace nbtf::cli {
namespace {

std::string humanBytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) bytes /= 1024, ++u;
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.2f %s", bytes, units[u]);
  return buf;
}

int infoStack(const std::string& path, const cxxopts::ParseResult& args) {
  LoadOptions options;
  if (args.count("layout")) options.layout = parseLayout(args["layout"].as<std::string>());
  if (args.count("crop")) options.crop = parseCrop(args["crop"].as<std::string>());
  BtfStack stack = loadBtfStack(path, options);
  float lo, hi;
  stack.valueRange(lo, hi);
  std::printf("source         %s\n", path.c_str());
  std::printf("layout         %s%s\n", layoutName(stack.layout).c_str(), args.count("layout") ? " (forced)" : " (detected)");
  std::printf("lights         %d\n", stack.numLights());
  std::printf("views          %d\n", stack.numViews());
  std::printf("images         %d\n", stack.numImages());
  std::printf("image size     %d x %d on disk\n", stack.sourceWidth, stack.sourceHeight);
  if (!stack.crop.empty())
    std::printf("crop           %d,%d,%d,%d -> %d x %d texels\n", stack.crop.x, stack.crop.y, stack.crop.width,
                stack.crop.height, stack.width(), stack.height());
  std::printf("texels         %d\n", stack.numTexels());
  std::printf("samples        %s\n", sampleTypeName(stack.sampleType()).c_str());
  std::printf("value range    %.6g .. %.6g (linear RGB)\n", lo, hi);
  std::printf("in memory      %s (%zu bytes)\n", humanBytes(stack.bytesInMemory()).c_str(), stack.bytesInMemory());
  std::printf("raw float32    %s (%zu bytes)\n", humanBytes(stack.rawFloat32Bytes()).c_str(), stack.rawFloat32Bytes());
  return 0;
}

// A .nbtf file: recognised by its magic bytes, or by its extension (so a damaged file
// still gets the reader's precise error instead of "not a folder").
bool looksLikeNbtf(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  return hasNbtfMagic(path) || std::filesystem::path(path).extension() == ".nbtf";
}

int infoNbtf(const std::string& path, const cxxopts::ParseResult& args) {
  for (const char* stackOnly : {"layout", "crop"})
    if (args.count(stackOnly))
      throw Error(std::string("--") + stackOnly + " applies to image stacks, not to .nbtf files");
  std::vector<std::uint8_t> bytes = readFileBytes(path);
  CompressedBtf btf = parseNbtf(bytes.data(), bytes.size(), path);
  std::fputs(describeNbtf(btf, path, bytes.size()).c_str(), stdout);
  return 0;
}

}  // namespace

int infoMain(int argc, char** argv) {
  return runGuarded("info", [&] {
    cxxopts::Options options("nbtf info", "Describe a BTF image stack folder or a compressed .nbtf file");
    options.positional_help("<path>");
    options.add_options()("path", "BTF stack folder or .nbtf file", cxxopts::value<std::string>())(
        "layout", "Force the layout: ubo2003 or utia", cxxopts::value<std::string>())(
        "crop", "Crop X,Y,W,H applied while loading", cxxopts::value<std::string>())(
        "q,quiet", "No progress bar");
    addCommonOptions(options);
    options.parse_positional({"path"});
    cxxopts::ParseResult args;
    if (!parseOptions(options, argc, argv, args)) return 0;
    applyCommonOptions(args);
    if (args.count("quiet")) Progress::setQuiet(true);
    if (!args.count("path")) throw Error("missing <path> (see 'nbtf info --help')");
    std::string path = args["path"].as<std::string>();
    return looksLikeNbtf(path) ? infoNbtf(path, args) : infoStack(path, args);
  });
}

}  // namespace nbtf::cli
