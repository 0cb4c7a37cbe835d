// nbtf view <file.nbtf> -o viewer.html: one self-contained WebGL2 page showing the material
// live (src/shader/viewer_page.h, docs/shader.md); --reference STACK adds the measured images.
#include <cstdio>
#include <filesystem>

#include "cli_common.h"
#include "codec/nbtf_file.h"
#include "commands.h"
#include "eval/evaluate_file.h"
#include "io/btf_loader.h"
#include "io/color.h"
#include "shader/shader_export.h"
#include "shader/viewer_page.h"
#include "util/atomic_file.h"

namespace nbtf::cli {
namespace {

// The stack's images at the file's texels, sRGB 8-bit: every measured pair, or where they do
// not fit the page the pairs viewerReferenceDirections spreads over the hemisphere. The stack
// must be the file's material (its source fingerprint, as nbtf eval checks it) unless --force.
ViewerReference loadReference(const std::string& stackPath, const std::string& file, const CompressedBtf& material,
                              const cxxopts::ParseResult& args) {
  LoadOptions options;
  if (auto layout = layoutOption(args)) options.layout = *layout;
  options.crop = cropOption(args).value_or(material.crop);
  options.progress = !quiet(args);
  // Chosen from the names before any image is read: a reference whose one image cannot fit
  // the page is refused before loading.
  const StackListing listing = listBtfStack(stackPath, options.layout);
  const ViewerReferenceSelection chosen =
      viewerReferenceDirections(listing.lights, listing.views, static_cast<std::size_t>(material.numTexels()));
  BtfStack stack = loadBtfStack(stackPath, options);
  if (stack.width() != material.width || stack.height() != material.height)
    throw Error("--reference " + stackPath + ": its images are " + std::to_string(stack.width()) + " x " +
                std::to_string(stack.height()) + " texels (after the crop), the file's " +
                std::to_string(material.width) + " x " + std::to_string(material.height) + " (use --crop)");
  ViewerReference r;
  r.fingerprintCheck = checkReferenceFingerprint(material, stack, file, stackPath, args.count("force") > 0, "nbtf view");
  r.name = stackPath;
  r.width = stack.width();
  r.height = stack.height();
  r.measuredLights = stack.numLights();
  r.measuredViews = stack.numViews();
  for (int l : chosen.lights) r.lights.push_back(stack.lights()[l]);
  for (int v : chosen.views) r.views.push_back(stack.views()[v]);
  const std::size_t imageValues = static_cast<std::size_t>(stack.numTexels()) * 3;
  r.srgb.resize(chosen.lights.size() * chosen.views.size() * imageValues);
  std::vector<float> rgb(imageValues);
  std::uint8_t* out = r.srgb.data();
  const Srgb8Encoder& encode = srgb8Encoder();
  for (int l : chosen.lights)
    for (int v : chosen.views) {
      stack.imageLinear(l * stack.numViews() + v, rgb.data());
      for (float x : rgb) *out++ = encode(x);
    }
  if (!quiet(args) && (r.lights.size() < static_cast<std::size_t>(r.measuredLights) ||
                       r.views.size() < static_cast<std::size_t>(r.measuredViews)))
    std::printf("reference: %zu of %d lights x %zu of %d views embedded (%zu MiB of 8-bit images; the page holds "
                "at most %zu MiB)\n",
                r.lights.size(), r.measuredLights, r.views.size(), r.measuredViews, r.srgb.size() >> 20,
                kMaxViewerReferenceBytes >> 20);
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
        "reference",
        "The image stack the file was made from (its source fingerprint is checked): the page shows the measured "
        "image at the nearest embedded pair beside. It embeds every measured pair in 8-bit sRGB when they fit " +
            std::to_string(kMaxViewerReferenceBytes >> 20) +
            " MiB, else the same fraction of the lights and of the views, spread over the hemisphere (at 100 x 100 "
            "texels 40 of 81 each)",
        cxxopts::value<std::string>())(
        "force", "Use a --reference that does not match the file's source fingerprint (the page says so)")("title", "Title shown in the page (default: the file name)",
                                       cxxopts::value<std::string>())(
        "weights", "Where the decoder's weights live: auto (uniform blocks when they fit 12 of 16 KiB), texture, "
                   "uniform-blocks", cxxopts::value<std::string>()->default_value("auto"));
    addStackOptions(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "file", argc, argv, args)) return 0;
    if (!args.count("file")) throw Error("missing <file.nbtf> (see 'nbtf view --help')");
    if (!args.count("output")) throw Error("missing -o (the page to write, e.g. viewer.html)");
    if (!args.count("reference") && (args.count("crop") || args.count("layout") || args.count("force")))
      throw Error("--crop, --layout and --force apply to the --reference stack");
    const std::string path = args["file"].as<std::string>(), output = args["output"].as<std::string>();
    const std::string referencePath = args.count("reference") ? args["reference"].as<std::string>() : "";
    refuseOverlappingPaths({{"<file.nbtf>", path}, {"--reference", referencePath}}, {{"-o", output}});
    const ShaderWeights weights = parseShaderWeights(args["weights"].as<std::string>());
    // The page's folder (and its missing parents) is made once there is a page to write.
    checkFolderCreatable(std::filesystem::path(output).parent_path().empty() ? std::string(".") :
                         std::filesystem::path(output).parent_path().string());
    const CompressedBtf material = readNbtf(path);
    const ShaderDecoder shader = buildShaderDecoder(material, path, weights);
    ViewerOptions o;
    if (args.count("title")) o.title = args["title"].as<std::string>();
    ViewerReference reference;
    if (args.count("reference")) {
      reference = loadReference(referencePath, path, material, args);
      o.reference = &reference;
    }
    const std::string page = buildViewerPage(shader, material, o);
    createParentFolders(output);
    writeFileAtomic(output, page);
    if (!quiet(args))
      std::printf("wrote %s (%.1f KiB): open it in a browser with WebGL2; nothing is fetched from the network\n",
                  output.c_str(), page.size() / 1024.0);
    return 0;
  });
}

}  // namespace nbtf::cli
