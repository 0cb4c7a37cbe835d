// nbtf decode <file.nbtf> -o <dir>: reconstruct the image stack (all measured images, a
// subset, or unmeasured angles) in the layout and naming the loaders read.
#include <cstdio>
#include <filesystem>
#include <tuple>

#include "cli_common.h"
#include "codec/decoder.h"
#include "pipeline/decoder_output.h"
#include "commands.h"
#include "interrupt.h"
#include "util/atomic_file.h"
#include "util/progress.h"

namespace nbtf::cli {

int decodeMain(int argc, char** argv) {
  return runGuarded("decode", [&] {
    cxxopts::Options options("nbtf decode",
                             "Reconstruct a BTF image stack from a .nbtf file (all images, a subset, or any angles)");
    options.positional_help("<file.nbtf> -o <dir>");
    options.add_options()("file", "Compressed material (.nbtf)", cxxopts::value<std::string>())(
        "o,output",
        "Output folder: new, empty, or an earlier nbtf decode (replaced as a whole once every image is written); "
        "ubo2014: the .btf file",
        cxxopts::value<std::string>())(
        "layout",
        "Output layout and names: ubo2003 or utia (default: the source's), or ubo2014: one Bonn .btf file at -o",
        cxxopts::value<std::string>())(
        "components", "ubo2014: SVD components per colour channel", cxxopts::value<int>()->default_value("32"))(
        "color-model", "ubo2014: 11 (log Y, U/Y, V/Y) or 0 (RGB)", cxxopts::value<int>()->default_value("11"))(
        "format", "png or jpg (8-bit sRGB) or exr (linear half float) (default: exr for half-float sources, else png)",
        cxxopts::value<std::string>())(
        "lights", "Lights to decode: 'all' or comma-separated N, N-M, tTHETApPHI (e.g. 0-5,t37.5p200)",
        cxxopts::value<std::string>())("views", "Views to decode, same LIST syntax as --lights",
                                       cxxopts::value<std::string>())(
        "light", "One light THETA,PHI in degrees (measured or not); same as --lights tTHETApPHI",
        cxxopts::value<std::string>())("view", "One view THETA,PHI in degrees; same as --views tTHETApPHI",
                                       cxxopts::value<std::string>())(
        "size", "Output image size WxH; the texture tiles (wraps) to fill it (default: the material's)",
        cxxopts::value<std::string>())("jpeg-quality", "JPEG quality 1..100",
                                       cxxopts::value<int>()->default_value("95"));
    addDecoderIsaOption(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "file", argc, argv, args)) return 0;
    const bool quiet = cli::quiet(args);
    if (!args.count("file")) throw Error("missing <file.nbtf> (see 'nbtf decode --help')");
    if (!args.count("output")) throw Error("missing -o <dir> (see 'nbtf decode --help')");
    for (auto [one, list] : {std::pair{"light", "lights"}, std::pair{"view", "views"}})
      if (args.count(one) && args.count(list))
        throw Error(std::string("--") + one + " and --" + list + " both choose the " + list + "; give one of them");

    const std::string file = args["file"].as<std::string>(), output = args["output"].as<std::string>();
    DecodeStackOptions o;
    if (args.count("layout")) o.layout = parseLayout(args["layout"].as<std::string>());
    refuseOverlappingPaths({{"<file.nbtf>", file}}, {{"-o", output, o.layout != Layout::Ubo2014}});
    DecoderOptions decoderOptions;
    decoderOptions.isa = decoderIsaOption(args);
    NbtfDecoder decoder = NbtfDecoder::open(file, decoderOptions);

    if (args.count("format")) o.format = parseImageFormat(args["format"].as<std::string>());
    if (args.count("lights")) o.lights = parseDirectionList(args["lights"].as<std::string>(), decoder.lights(), "--lights");
    if (args.count("views")) o.views = parseDirectionList(args["views"].as<std::string>(), decoder.views(), "--views");
    if (args.count("light"))
      o.lights = {chooseDirection(parseDirection(args["light"].as<std::string>(), "--light"), decoder.lights())};
    if (args.count("view"))
      o.views = {chooseDirection(parseDirection(args["view"].as<std::string>(), "--view"), decoder.views())};
    if (args.count("size")) std::tie(o.width, o.height) = parseImageSize(args["size"].as<std::string>(), "--size");
    o.jpegQuality = args["jpeg-quality"].as<int>();
    o.progress = !quiet;

    if (o.layout == Layout::Ubo2014) {
      Ubo2014FactorizeOptions f;
      f.components = args["components"].as<int>();
      f.colorModel = args["color-model"].as<int>();
      createParentFolders(output);
      DecodeUbo2014Result r = writeDecodedUbo2014(decoder, output, o, f);
      std::fputs(formatDecodeUbo2014Summary(r).c_str(), stdout);
      return 0;
    }
    for (const char* only : {"components", "color-model"})
      if (args.count(only)) throw Error(std::string("--") + only + " applies to --layout ubo2014 only");
    o.stopFlag = stopOnInterrupt("\nnbtf decode: interrupt received, stopping after the images being written "
                                 "(Ctrl-C again to abort)\n");
    DecodeStackResult result = writeDecodedStack(decoder, output, o);
    if (result.interrupted) {
      std::fprintf(stderr,
                   "nbtf decode: interrupted after %d of %d images; they were in a staging folder, now removed: "
                   "nothing was written to %s%s\n",
                   result.written, result.images, output.c_str(),
                   std::filesystem::exists(output) ? " (what was there is unchanged)" : "");
      return 130;
    }
    std::fputs(formatDecodeSummary(result, decoder).c_str(), stdout);  // -q hides progress only, as everywhere
    return 0;
  });
}

}  // namespace nbtf::cli
