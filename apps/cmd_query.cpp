// nbtf query <file.nbtf>: decoded RGB for one (texel, light, view) or a CSV batch.
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "cli_common.h"
#include "codec/decoder.h"
#include "codec/decoder_query.h"
#include "commands.h"

namespace nbtf::cli {
namespace {

std::pair<float, float> parsePair(const std::string& text, const std::string& option, bool integers) {
  std::istringstream in(text);
  double a = 0, b = 0;
  char comma = 0;
  if (!(in >> a >> comma >> b) || comma != ',' || !(in >> std::ws).eof() || !std::isfinite(a) || !std::isfinite(b) ||
      (integers && (a != std::floor(a) || b != std::floor(b))))
    throw Error(option + ": expected " + (integers ? "X,Y (integers)" : "U,V (numbers)") + ", got '" + text + "'");
  return {static_cast<float>(a), static_cast<float>(b)};
}

}  // namespace

int queryMain(int argc, char** argv) {
  return runGuarded("query", [&] {
    cxxopts::Options options("nbtf query", "Decoded RGB of a .nbtf material at texels and directions");
    options.positional_help("<file.nbtf> (--texel X,Y | --uv U,V) --light THETA,PHI --view THETA,PHI | --batch FILE");
    options.add_options()("file", "Compressed material (.nbtf)", cxxopts::value<std::string>())(
        "texel", "Texel X,Y of the material (0-based, y = 0 the top row)", cxxopts::value<std::string>())(
        "uv", "Texture coordinate U,V instead of --texel (wraps: the texture tiles)", cxxopts::value<std::string>())(
        "light", "Light THETA,PHI in degrees", cxxopts::value<std::string>())(
        "view", "View THETA,PHI in degrees", cxxopts::value<std::string>())(
        "batch", "CSV file of queries x,y,theta_l,phi_l,theta_v,phi_v ('-' = standard input); answers as CSV",
        cxxopts::value<std::string>())("batch-lines", "Lines read before answering (1 = answer every line at once)",
                                       cxxopts::value<std::size_t>()->default_value("8192"))(
        "normalized", "Print the decoder output (linear / alpha) instead of linear RGB");
    addDecoderIsaOption(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "file", argc, argv, args)) return 0;
    if (!args.count("file")) throw Error("missing <file.nbtf> (see 'nbtf query --help')");
    const OutputScale scale = args.count("normalized") ? OutputScale::Normalized : OutputScale::Linear;
    const bool batch = args.count("batch") > 0;
    if (batch) {
      for (const char* single : {"texel", "uv", "light", "view"})
        if (args.count(single))
          throw Error(std::string("--") + single + " is for a single query; --batch reads every query from its file");
    } else {
      if (args.count("texel") + args.count("uv") != 1)
        throw Error("give exactly one of --texel X,Y and --uv U,V (or --batch FILE)");
      if (!args.count("light") || !args.count("view")) throw Error("a single query needs --light and --view");
    }

    DecoderOptions decoderOptions;
    decoderOptions.isa = decoderIsaOption(args);
    NbtfDecoder decoder = NbtfDecoder::open(args["file"].as<std::string>(), decoderOptions);

    if (!batch) {
      Direction light = parseDirection(args["light"].as<std::string>(), "--light");
      Direction view = parseDirection(args["view"].as<std::string>(), "--view");
      Rgb rgb;
      if (args.count("texel")) {
        auto [x, y] = parsePair(args["texel"].as<std::string>(), "--texel", true);
        rgb = decoder.evaluate(static_cast<int>(x), static_cast<int>(y), light, view, scale);
      } else {
        auto [u, v] = parsePair(args["uv"].as<std::string>(), "--uv", false);
        rgb = decoder.evaluateUv(u, v, light, view, scale);
      }
      std::cout << formatRgb(rgb) << std::endl;
      return 0;
    }

    QueryCsvOptions o;
    o.scale = scale;
    o.batchLines = args["batch-lines"].as<std::size_t>();
    const std::string source = args["batch"].as<std::string>();
    QueryCsvStats stats;
    if (source == "-") {
      stats = answerQueryCsv(decoder, std::cin, "<stdin>", std::cout, std::cerr, o);
    } else {
      if (isFolder(source)) throw fileError(source, "is a folder; --batch reads a CSV file of queries (or '-')");
      std::ifstream in(source);
      if (!in) throw fileError(source, "cannot open the query file");
      stats = answerQueryCsv(decoder, in, source, std::cout, std::cerr, o);
    }
    if (stats.malformed) {
      std::cerr << "nbtf query: " << stats.malformed << " malformed line" << (stats.malformed == 1 ? "" : "s")
                << " skipped, " << stats.answered << " quer" << (stats.answered == 1 ? "y" : "ies") << " answered"
                << std::endl;
      return 1;
    }
    return 0;
  });
}

}  // namespace nbtf::cli
