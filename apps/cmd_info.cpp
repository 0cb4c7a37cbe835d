// nbtf info <path>: describe a BTF image stack folder or a compressed .nbtf file.
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

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

nlohmann::json directionsJson(const std::vector<Direction>& dirs) {
  nlohmann::json a = nlohmann::json::array();
  for (std::size_t i = 0; i < dirs.size(); ++i)
    a.push_back({{"index", i}, {"theta_deg", dirs[i].thetaDeg}, {"phi_deg", dirs[i].phiDeg}});
  return a;
}

// --directions: the indices that `decode --lights` / `--views` take (N, N-M), with angles.
void printDirections(const std::vector<Direction>& lights, const std::vector<Direction>& views, bool json) {
  if (json) {
    std::printf("%s\n", nlohmann::json{{"lights", directionsJson(lights)}, {"views", directionsJson(views)}}.dump(2).c_str());
    return;
  }
  for (auto [name, dirs] : {std::pair{"light", &lights}, std::pair{"view", &views}}) {
    std::printf("%ss (%zu; index: theta, phi in degrees; 'decode --%ss 0-5' takes these indices)\n", name, dirs->size(),
                name);
    for (std::size_t i = 0; i < dirs->size(); ++i)
      std::printf("  %4zu  %6.2f  %6.2f\n", i, (*dirs)[i].thetaDeg, (*dirs)[i].phiDeg);
  }
}

int infoStack(const std::string& path, const cxxopts::ParseResult& args) {
  LoadOptions options;
  if (args.count("layout")) options.layout = parseLayout(args["layout"].as<std::string>());
  if (args.count("crop")) options.crop = parseCrop(args["crop"].as<std::string>());
  const bool json = args.count("json") > 0;
  if (args.count("directions")) {  // the names alone say the directions: no image is read
    StackListing listing = listBtfStack(path, options.layout);
    printDirections(listing.lights, listing.views, json);
    return 0;
  }
  options.progress = !quiet(args) && !json;
  BtfStack stack = loadBtfStack(path, options);
  float lo, hi;
  stack.valueRange(lo, hi);
  if (json) {
    nlohmann::json j;
    j["kind"] = "stack";
    j["source"] = path;
    j["layout"] = layoutName(stack.layout);
    j["layout_forced"] = args.count("layout") > 0;
    j["lights"] = stack.numLights();
    j["views"] = stack.numViews();
    j["images"] = stack.numImages();
    j["image_size"] = {stack.sourceWidth, stack.sourceHeight};
    j["crop"] = stack.crop.empty() ? nlohmann::json(nullptr)
                                   : nlohmann::json{stack.crop.x, stack.crop.y, stack.crop.width, stack.crop.height};
    j["width"] = stack.width();
    j["height"] = stack.height();
    j["texels"] = stack.numTexels();
    j["samples"] = sampleTypeName(stack.sampleType());
    j["value_range_linear"] = {lo, hi};
    j["bytes_in_memory"] = stack.bytesInMemory();
    j["bytes_raw_float32"] = stack.rawFloat32Bytes();
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
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
  const bool json = args.count("json") > 0;
  if (args.count("directions")) {
    printDirections(btf.lights, btf.views, json);
    return 0;
  }
  if (!json) {
    std::fputs(describeNbtf(btf, path, bytes.size()).c_str(), stdout);
    return 0;
  }
  const NbtfSizes sizes = computeSizes(btf, bytes.size());
  nlohmann::json j;
  j["kind"] = "nbtf";
  j["file"] = path;
  j["format_version"] = std::to_string(btf.formatMajor) + "." + std::to_string(btf.formatMinor);
  j["method"] = codecMethodName(btf.method);
  j["width"] = btf.width;
  j["height"] = btf.height;
  j["image_size"] = {btf.sourceWidth, btf.sourceHeight};
  j["crop"] = btf.crop.empty() ? nlohmann::json(nullptr)
                               : nlohmann::json{btf.crop.x, btf.crop.y, btf.crop.width, btf.crop.height};
  j["layout"] = layoutName(btf.layout);
  j["lights"] = btf.lights.size();
  j["views"] = btf.views.size();
  j["images"] = btf.numImages();
  j["clusters"] = btf.numClusters();
  j["latent_dim"] = btf.latentDim;
  j["latent_rows"] = btf.latentRows;
  j["pca_components"] = btf.pcaComponents();
  j["alpha"] = btf.alpha;
  j["holdout_images"] = btf.holdoutImages.size();
  j["bytes"] = {{"decoder", sizes.decoder}, {"latents", sizes.latents}, {"ids", sizes.ids},
                {"total", sizes.total},     {"raw_float32", sizes.rawFloat32}, {"file", sizes.fileBytes}};
  j["ratio"] = sizes.ratio;
  nlohmann::json meta = nlohmann::json::parse(btf.metadataJson, nullptr, /*allow_exceptions=*/false);
  j["metadata"] = meta.is_discarded() ? nlohmann::json(nullptr) : meta;
  std::printf("%s\n", j.dump(2).c_str());
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
        "json", "Print the description as JSON")(
        "directions", "List the light and view directions with the indices 'decode --lights/--views' take");
    addCommonOptions(options);
    options.parse_positional({"path"});
    cxxopts::ParseResult args;
    if (!parseOptions(options, argc, argv, args)) return 0;
    applyCommonOptions(args, options.program());
    if (!args.count("path")) throw Error("missing <path> (see 'nbtf info --help')");
    std::string path = args["path"].as<std::string>();
    return looksLikeNbtf(path) ? infoNbtf(path, args) : infoStack(path, args);
  });
}

}  // namespace nbtf::cli
