// nbtf-synth: renders a synthetic BTF material under all 81 x 81 light/view pairs and
// writes it in the UBO2003 or UTIA layout, with its linear float ground truth; or under the
// 151 x 151 pairs of Bonn's Dome 1 as a UBO2014 .btf file (factorized, half floats).
#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>
#include <sstream>

#include "synth/synth_material.h"
#include "synth/synth_ubo2014.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace {
using namespace nbtf;

// "WxH" or "N" (square) -> width, height.
void parseSize(const std::string& text, int& width, int& height) {
  std::istringstream in(text);
  char x = 0;
  if (!(in >> width)) throw Error("--size: expected WxH (e.g. 100x100), got '" + text + "'");
  if (in >> x) {
    if ((x != 'x' && x != 'X') || !(in >> height)) throw Error("--size: expected WxH (e.g. 100x100), got '" + text + "'");
  } else {
    height = width;
  }
  in.clear();
  if (!(in >> std::ws).eof()) throw Error("--size: expected WxH (e.g. 100x100), got '" + text + "'");
  if (width <= 0 || height <= 0) throw Error("--size: '" + text + "' must be positive");
}

int run(int argc, char** argv) {
  cxxopts::Options options("nbtf-synth", "Render a synthetic BTF material (81 x 81 light/view images) with its ground truth");
  options.add_options()("preset", "Material preset (see --list-presets)", cxxopts::value<std::string>()->default_value("fabric"))(
      "size", "Texels WxH (or N for N x N), 8 to 1024 each", cxxopts::value<std::string>()->default_value("100x100"))(
      "layout", "ubo2003 (JPEG), utia (PNG or EXR) or ubo2014 (one .btf file, 151 x 151 directions)",
      cxxopts::value<std::string>()->default_value("ubo2003"))(
      "components", "ubo2014: SVD components per colour channel", cxxopts::value<int>()->default_value("32"))(
      "color-model", "ubo2014: 11 (log Y, U/Y, V/Y) or 0 (RGB)", cxxopts::value<int>()->default_value("11"))(
      "power-iterations", "ubo2014: power iterations of the randomized SVD (each one more 2 passes when streamed)",
      cxxopts::value<int>()->default_value("2"))(
      "memory-limit",
      "ubo2014: hold the rendered material (images x texels x 12 bytes) up to half this size, else render it "
      "again for each pass of the factorization (default: 75% of physical memory)",
      cxxopts::value<std::string>())(
      "format", "jpg (ubo2003), png or exr (utia); default: jpg for ubo2003, png for utia", cxxopts::value<std::string>())(
      "seed", "Random seed: the same seed gives the same material", cxxopts::value<std::uint64_t>()->default_value("1"))(
      "o,output", "Output folder (new, empty, or an earlier nbtf-synth output to replace); ubo2014: the .btf file",
      cxxopts::value<std::string>())(
      "no-parallax", "Shade the texel below instead of the one seen along the view ray (masking only)")(
      "no-ground-truth", "Do not write the float ground truth")(
      "supersampling", "Fine samples per texel along each axis (1 to 4)", cxxopts::value<int>()->default_value("2"))(
      "list-presets", "List the presets and exit")(
      "threads", "Worker threads (0 = all cores)", cxxopts::value<int>()->default_value("0"))(
      "q,quiet", "No progress bar")("h,help", "Show this help");
  cxxopts::ParseResult args;
  try {
    args = options.parse(argc, argv);
  } catch (const std::exception& e) {
    throw Error(std::string(e.what()) + " (see 'nbtf-synth --help')");
  }
  if (args.count("help")) {
    std::cout << options.help() << std::endl;
    return 0;
  }
  if (args.count("list-presets")) {
    for (const std::string& name : synth::presetNames())
      std::printf("%-10s %s\n", name.c_str(), synth::presetDescription(name).c_str());
    return 0;
  }
  if (!args.unmatched().empty()) throw Error("unexpected argument '" + args.unmatched().front() + "' (see 'nbtf-synth --help')");
  int threads = args["threads"].as<int>();
  if (threads < 0) throw Error("--threads must be >= 0, got " + std::to_string(threads));
  setThreadCount(threads);
  if (args.count("quiet")) Progress::setQuiet(true);
  if (!args.count("output")) throw Error("missing -o DIR, the output folder (see 'nbtf-synth --help')");

  synth::SynthOptions o;
  o.preset = args["preset"].as<std::string>();
  parseSize(args["size"].as<std::string>(), o.width, o.height);
  o.layout = parseLayout(args["layout"].as<std::string>());
  if (o.layout != Layout::Ubo2014)
    for (const char* only : {"components", "color-model", "power-iterations", "memory-limit"})
      if (args.count(only)) throw Error(std::string("--") + only + " applies to --layout ubo2014 only");
  if (o.layout == Layout::Ubo2014) {
    for (const char* imagesOnly : {"format", "no-ground-truth"})
      if (args.count(imagesOnly))
        throw Error(std::string("--") + imagesOnly + " does not apply to --layout ubo2014 (one .btf file, no images)");
    o.seed = args["seed"].as<std::uint64_t>();
    o.render.parallax = !args.count("no-parallax");
    o.render.supersampling = args["supersampling"].as<int>();
    Ubo2014FactorizeOptions f;
    f.components = args["components"].as<int>();
    f.colorModel = args["color-model"].as<int>();
    f.powerIterations = args["power-iterations"].as<int>();
    if (args.count("memory-limit"))
      f.memoryLimit = parseByteSize(args["memory-limit"].as<std::string>(), "--memory-limit") / 2;
    const std::string out = args["output"].as<std::string>();
    synth::SynthUbo2014Summary s = synth::writeSynthUbo2014(o, out, f);
    std::printf("wrote %s (ubo2014, !DFMF08FCR, %d images = 151 x 151, %d x %d texels, %d components per channel, "
                "colour model %d, %zu bytes, preset %s, seed %llu) in %.1f s\n",
                out.c_str(), s.images, o.width, o.height, s.factorization.components, f.colorModel, s.fileBytes,
                o.preset.c_str(), static_cast<unsigned long long>(o.seed), s.seconds);
    std::printf("factorization (stored half floats vs the rendered values, linear sRGB): RMSE %.4g (mean value %.4g), "
                "max abs error %.4g\n",
                s.factorization.rmseLinear, s.factorization.inputMean, s.factorization.maxAbsError);
    if (s.factorization.streamed)
      std::printf("streamed: the material (%s in float32) was rendered %d times instead of held; peak %s resident\n",
                  formatBytes(ubo2014MatrixBytes(s.images, o.width * o.height)).c_str(), s.factorization.passes,
                  formatBytes(peakResidentBytes()).c_str());
    return 0;
  }
  o.format = args.count("format") ? parseImageFormat(args["format"].as<std::string>())
                                  : (o.layout == Layout::Utia ? ImageFormat::Png : ImageFormat::Jpg);
  o.seed = args["seed"].as<std::uint64_t>();
  o.render.parallax = !args.count("no-parallax");
  o.render.supersampling = args["supersampling"].as<int>();
  o.groundTruth = !args.count("no-ground-truth");
  synth::validateSynthOptions(o);
  const std::string out = args["output"].as<std::string>();

  synth::SynthSummary s = synth::writeSynthStack(o, out);
  std::printf("wrote %d images (%s, %s, %d x %d texels, preset %s, seed %llu)%s to %s in %.1f s\n", s.images,
              layoutName(o.layout).c_str(), extensionOf(o.format).substr(1).c_str(), o.width, o.height,
              o.preset.c_str(), static_cast<unsigned long long>(o.seed),
              o.groundTruth ? (" + " + std::to_string(s.groundTruthFiles) + " ground-truth EXRs").c_str() : "",
              out.c_str(), s.seconds);
  std::printf("values (linear sRGB, exact): min %.4g, max %.4g, mean %.4g; %.2f%% of samples above 1 (clip in 8-bit)\n",
              s.minValue, s.maxValue, s.meanValue, 100 * s.clippedFraction);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  nbtf::reuseFreedMemory();
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "nbtf-synth: error: " << userMessage(e) << std::endl;
    return 1;
  }
}
