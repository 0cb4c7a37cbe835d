// nbtf info <path>: describe a BTF image stack folder or a compressed .nbtf file.
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_common.h"
#include "codec/nbtf_describe.h"
#include "codec/nbtf_file.h"
#include "codec/nbtf_info.h"
#include "commands.h"
#include "io/btf_loader.h"
#include "io/ubo2014_btf.h"
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
  if (auto layout = layoutOption(args)) options.layout = *layout;
  if (auto crop = cropOption(args)) options.crop = *crop;
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

// A UBO2014 .btf file: described from its header and factors, never expanded.
int infoBtf(const std::string& path, const cxxopts::ParseResult& args) {
  if (args.count("layout")) throw Error("--layout applies to image stacks, not to .btf files");
  Ubo2014Btf btf = Ubo2014Btf::read(path);
  Crop crop = cropOption(args).value_or(Crop{});
  if (!crop.empty()) {
    LoadOptions o;
    o.crop = crop;
    checkCrop(path, o);
  }
  const int w = crop.empty() ? btf.width() : crop.width, h = crop.empty() ? btf.height() : crop.height;
  const std::size_t expandedHalf = static_cast<std::size_t>(btf.numImages()) * w * h * 3 * 2;
  const bool json = args.count("json") > 0;
  if (args.count("directions")) {
    printDirections(btf.meta().lights, btf.meta().views, json);
    return 0;
  }
  const Ubo2014Meta& m = btf.meta();
  std::string components;
  for (const Ubo2014Channel& ch : btf.channels())
    components += (components.empty() ? "" : ", ") + std::to_string(ch.components);
  if (json) {
    nlohmann::json j;
    j["kind"] = "ubo2014";
    j["source"] = path;
    j["layout"] = "ubo2014";
    j["signature"] = m.signature;
    j["lights"] = btf.numLights();
    j["views"] = btf.numViews();
    j["images"] = btf.numImages();
    j["image_size"] = {btf.width(), btf.height()};
    j["crop"] = crop.empty() ? nlohmann::json(nullptr) : nlohmann::json{crop.x, crop.y, crop.width, crop.height};
    j["width"] = w;
    j["height"] = h;
    j["texels"] = w * h;
    j["color_model"] = {{"code", m.colorModel}, {"name", uboColorModelName(m.colorModel)}};
    nlohmann::json ch = nlohmann::json::array();
    for (const Ubo2014Channel& c : btf.channels())
      ch.push_back({{"components", c.components}, {"scalar_bytes", c.scalarSize}, {"u_rows", c.uRows},
                    {"sxv_rows", c.sxvRows}});
    j["channels"] = ch;
    j["abrdfs_in_u"] = btf.abrdfsInU();
    j["cosine_flag"] = m.cosineFlag != 0;
    j["measurement_setup"] = m.measurementSetup;
    j["bytes_factors_in_memory"] = btf.factorBytes();
    j["bytes_expanded_half"] = expandedHalf;
    j["bytes_raw_float32"] = static_cast<std::size_t>(btf.numImages()) * w * h * 3 * 4;
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("source         %s\n", path.c_str());
  std::printf("layout         ubo2014 (signature %s)\n", m.signature.c_str());
  std::printf("lights         %d\n", btf.numLights());
  std::printf("views          %d\n", btf.numViews());
  std::printf("images         %d\n", btf.numImages());
  std::printf("image size     %d x %d in the file\n", btf.width(), btf.height());
  if (!crop.empty())
    std::printf("crop           %d,%d,%d,%d -> %d x %d texels\n", crop.x, crop.y, crop.width, crop.height, w, h);
  std::printf("texels         %d\n", w * h);
  std::printf("colour model   %d (%s)\n", m.colorModel, uboColorModelName(m.colorModel).c_str());
  std::printf("components     %s per channel (%s floats; ABRDF = U row x SxV^T, %s)\n", components.c_str(),
              btf.channels()[0].scalarSize == 2 ? "half" : btf.channels()[0].scalarSize == 4 ? "32-bit" : "64-bit",
              btf.abrdfsInU() ? "U rows are light/view pairs" : "U rows are texels");
  if (m.cosineFlag) std::printf("cosine         the file holds cos(theta_light) x reflectance; nbtf divides it out\n");
  if (!m.measurementSetup.empty()) std::printf("measured with  %s\n", m.measurementSetup.c_str());
  std::printf("in memory      %s (%zu bytes: the factors as floats; nothing is expanded to describe it)\n",
              humanBytes(btf.factorBytes()).c_str(), btf.factorBytes());
  std::printf("expanded       %s (%zu bytes: half floats, what compress/cluster/eval load%s)\n",
              humanBytes(expandedHalf).c_str(), expandedHalf, crop.empty() ? "; --crop loads less" : " for this crop");
  std::printf("raw float32    %s (%zu bytes)\n", humanBytes(2.0 * expandedHalf).c_str(), 2 * expandedHalf);
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
  std::printf("%s\n", nbtfInfoJson(btf, path, bytes.size()).c_str());
  return 0;
}

}  // namespace

int infoMain(int argc, char** argv) {
  return runGuarded("info", [&] {
    cxxopts::Options options("nbtf info", "Describe a BTF image stack folder, a UBO2014 .btf file or a compressed .nbtf file");
    options.positional_help("<path>");
    options.add_options()("path", "BTF stack folder, UBO2014 .btf file or .nbtf file", cxxopts::value<std::string>())(
        "json", "Print the description as JSON")(
        "directions", "List the light and view directions with the indices 'decode --lights/--views' take");
    addStackOptions(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "path", argc, argv, args)) return 0;
    if (!args.count("path")) throw Error("missing <path> (see 'nbtf info --help')");
    std::string path = args["path"].as<std::string>();
    if (looksLikeNbtf(path)) return infoNbtf(path, args);
    return looksLikeUbo2014(path) ? infoBtf(path, args) : infoStack(path, args);
  });
}

}  // namespace nbtf::cli
