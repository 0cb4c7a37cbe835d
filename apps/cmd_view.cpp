// nbtf view <file.nbtf> -o viewer.html: one self-contained WebGL2 page showing the material
// live (src/shader/viewer_page.h, docs/shader.md); --reference STACK adds the measured images.
#include <cstdio>

#include "cli_common.h"
#include "codec/nbtf_file.h"
#include "commands.h"
#include "io/btf_loader.h"
#include "io/color.h"
#include "shader/shader_export.h"
#include "shader/viewer_page.h"
#include "util/atomic_file.h"

namespace nbtf::cli {
namespace {

// The stack's images at the file's texels, sRGB 8-bit; refused before reading when too large.
ViewerReference loadReference(const std::string& stackPath, const CompressedBtf& material,
                              const cxxopts::ParseResult& args) {
  LoadOptions options;
  if (auto layout = layoutOption(args)) options.layout = *layout;
  options.crop = cropOption(args).value_or(material.crop);
  options.progress = !quiet(args);
  const StackListing listing = listBtfStack(stackPath, options.layout);
  const std::size_t bytes =
      listing.lights.size() * listing.views.size() * static_cast<std::size_t>(material.numTexels()) * 3;
  if (bytes > kMaxViewerReferenceBytes)
    throw Error("--reference " + stackPath + ": " + std::to_string(listing.lights.size() * listing.views.size()) +
                " images of " + std::to_string(material.width) + " x " + std::to_string(material.height) +
                " texels are " + std::to_string(bytes >> 20) + " MiB as 8-bit RGB, more than the " +
                std::to_string(kMaxViewerReferenceBytes >> 20) +
                " MiB the page embeds; pass a smaller stack or a smaller --crop");
  BtfStack stack = loadBtfStack(stackPath, options);
  if (stack.width() != material.width || stack.height() != material.height)
    throw Error("--reference " + stackPath + ": its images are " + std::to_string(stack.width()) + " x " +
                std::to_string(stack.height()) + " texels (after the crop), the file's " +
                std::to_string(material.width) + " x " + std::to_string(material.height) + " (use --crop)");
  ViewerReference r;
  r.name = stackPath;
  r.width = stack.width();
  r.height = stack.height();
  r.lights = stack.lights();
  r.views = stack.views();
  r.srgb.resize(static_cast<std::size_t>(stack.numImages()) * stack.numTexels() * 3);
  std::vector<float> rgb(static_cast<std::size_t>(stack.numTexels()) * 3);
  for (int i = 0; i < stack.numImages(); ++i) {
    stack.imageLinear(i, rgb.data());
    for (std::size_t k = 0; k < rgb.size(); ++k) r.srgb[static_cast<std::size_t>(i) * rgb.size() + k] = linearToSrgb8(rgb[k]);
  }
  return r;
}

}  // namespace

int viewMain(int argc, char** argv) {
  return runGuarded("view", [&] {
    cxxopts::Options options("nbtf view",
                             "One self-contained HTML page (WebGL2) showing a .nbtf material live: plane, sphere, "
                             "cloth; light and view under the mouse");
    options.positional_help("<file.nbtf> -o viewer.html [--reference STACK]");
    options.add_options()("file", "Compressed material (.nbtf)", cxxopts::value<std::string>())(
        "o,output", "The page to write (.html)", cxxopts::value<std::string>())(
        "reference", "Original image stack: show the measured image at the nearest measured pair beside (at most " +
                         std::to_string(kMaxViewerReferenceBytes >> 20) + " MiB of 8-bit images)",
        cxxopts::value<std::string>())("title", "Title shown in the page (default: the file name)",
                                       cxxopts::value<std::string>())(
        "weights", "Where the decoder's weights live: auto (uniform blocks when they fit 12 of 16 KiB), texture, "
                   "uniform-blocks", cxxopts::value<std::string>()->default_value("auto"));
    addStackOptions(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "file", argc, argv, args)) return 0;
    if (!args.count("file")) throw Error("missing <file.nbtf> (see 'nbtf view --help')");
    if (!args.count("output")) throw Error("missing -o (the page to write, e.g. viewer.html)");
    if (!args.count("reference") && (args.count("crop") || args.count("layout")))
      throw Error("--crop and --layout apply to the --reference stack");
    const std::string path = args["file"].as<std::string>(), output = args["output"].as<std::string>();
    const ShaderWeights weights = parseShaderWeights(args["weights"].as<std::string>());
    createParentFolders(output);  // the rule of every command's outputs
    checkWritable(output);
    const CompressedBtf material = readNbtf(path);
    const ShaderDecoder shader = buildShaderDecoder(material, path, weights);
    ViewerOptions o;
    if (args.count("title")) o.title = args["title"].as<std::string>();
    ViewerReference reference;
    if (args.count("reference")) {
      reference = loadReference(args["reference"].as<std::string>(), material, args);
      o.reference = &reference;
    }
    const std::string page = buildViewerPage(shader, material, o);
    writeFileAtomic(output, page);
    if (!quiet(args))
      std::printf("wrote %s (%.1f KiB): open it in a browser with WebGL2; nothing is fetched from the network\n",
                  output.c_str(), page.size() / 1024.0);
    return 0;
  });
}

}  // namespace nbtf::cli
