// nbtf render <material>: the material on an object, ray traced on the CPU, anti-aliased
// adaptively with automatic differentiation (adaptive oversampling) or uniformly; --compare renders an
// original stack and its .nbtf with the same scene and reports the difference.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_common.h"
#include "pipeline/decoder_output.h"
#include "codec/nbtf_file.h"
#include "commands.h"
#include "io/image_io.h"
#include "render/compare.h"
#include "render/integrator.h"
#include "render/material_source.h"
#include "render/scene.h"
#include "util/atomic_file.h"
#include "util/progress.h"

namespace nbtf::cli {
namespace {

void writeRender(const std::string& png, const std::string& exr, const RenderResult& r) {
  if (!png.empty()) writeImageSrgb8(png, imageFormatFromName(png), r.width, r.height, r.rgb.data());
  if (!exr.empty()) writeExr(exr, r.width, r.height, r.rgb.data(), false);
}

// White: one ray; grey: split once into 3 x 3; black: some sub-pixel split again.
void writeRefinedMask(const std::string& path, const RenderResult& r) {
  Image8 img;
  img.width = r.width, img.height = r.height;
  img.rgb.resize(static_cast<std::size_t>(r.width) * r.height * 3);
  for (std::size_t p = 0; p < r.refined.size(); ++p) {
    const std::uint8_t v = r.refined[p] == 0 ? 255 : r.refined[p] == 1 ? 128 : 0;
    img.rgb[3 * p] = img.rgb[3 * p + 1] = img.rgb[3 * p + 2] = v;
  }
  writeImage8(path, imageFormatFromName(path), img);
}

std::string samplingName(const RenderOptions& o) {
  if (o.mode == SamplingMode::Uniform) return "uniform " + std::to_string(o.uniform) + "x" + std::to_string(o.uniform);
  return "adaptive, " + std::to_string(o.levels) + " level" + (o.levels == 1 ? "" : "s");
}

nlohmann::json statsJson(const RenderResult& r, const RenderOptions& o) {
  const RenderStats& s = r.stats;
  nlohmann::json j;
  j["sampling"] = samplingName(o);
  j["width"] = r.width;
  j["height"] = r.height;
  j["seconds"] = s.seconds;
  j["derivative_rays"] = s.derivativeRays;
  j["plain_rays"] = s.plainRays;
  j["shadow_rays"] = s.shadowRays;
  j["corner_shadow_rays"] = s.cornerShadowRays;
  j["material_queries"] = s.materialQueries;
  j["pixels"] = s.pixels;
  j["refined_pixels"] = s.refinedPixels;
  j["refined_twice"] = s.refinedTwice;
  j["refined_fraction"] = s.pixels ? double(s.refinedPixels) / s.pixels : 0.0;
  for (int b = 0; b < kRefineReasons; ++b) j["refine_reasons"][refineReasonName(b)] = s.reasons[b];
  return j;
}

}  // namespace

namespace {
// --compare renders the measured stack beside the file made from it: measured at the same
// directions (the check eval makes), or the comparison means nothing.
void checkCompareDirections(const MaterialSource& reference, const MaterialSource& compressed) {
  const auto* stack = dynamic_cast<const StackMaterial*>(&reference);
  const auto* file = dynamic_cast<const NbtfMaterial*>(&compressed);
  if (!stack || !file) return;
  const std::string prefix = "--compare '" + reference.name() + "' does not match '" + compressed.name() + "': ";
  checkSameDirections(stack->stack().lights(), file->decoder().lights(), "light", prefix);
  checkSameDirections(stack->stack().views(), file->decoder().views(), "view", prefix);
}
}  // namespace

namespace {

cxxopts::Options renderOptions() {
  cxxopts::Options options("nbtf render", "Ray trace a BTF material on an object (adaptive anti-aliasing by automatic differentiation)");
  options.positional_help("<material: file.nbtf or image stack folder> -o image.png");
  options.add_options()("material", "A .nbtf file or an original image stack folder", cxxopts::value<std::string>())(
      "o,output", "Output image (PNG/JPG, sRGB); with --compare an output folder", cxxopts::value<std::string>())(
      "exr", "Also write the linear radiance as a float EXR", cxxopts::value<std::string>())(
      "scene", "plane, tile (the plane without its occluder), sphere, cylinder or cloth", cxxopts::value<std::string>()->default_value("sphere"))(
      "light", "Direction towards the light THETA,PHI in degrees (theta from +y up, phi from +x towards +z)",
      cxxopts::value<std::string>()->default_value("45,300"))(
      "camera", "EX,EY,EZ[,TX,TY,TZ[,FOV]]: eye, target, vertical field of view (default: the scene's)",
      cxxopts::value<std::string>())("size", "Image size WxH", cxxopts::value<std::string>()->default_value("320x240"))(
      "tiling", "Copies of the texture across the object's parametrization", cxxopts::value<double>()->default_value("1"))(
      "adaptive", "Adaptive oversampling by automatic differentiation (the default)")(
      "uniform", "N x N samples in every pixel instead", cxxopts::value<int>())(
      "spp", "Samples per pixel for uniform sampling (a square: 1, 4, 9, ...)", cxxopts::value<int>())(
      "levels", "Adaptive: levels of 3x3 refinement (1 or 2; 3 allowed)", cxxopts::value<int>()->default_value("2"))(
      "threshold", "Adaptive: split when a covered texel differs from the centre's by more (linear radiance)", cxxopts::value<double>()->default_value("0.08"))(
      "no-shadow-corners", "Adaptive: skip the corner shadow rule")(
      "no-derivative-tests", "Adaptive: skip the silhouette/terminator/shadow tests from derivatives")(
      "no-texture-test", "Adaptive: skip the texture test")(
      "no-footprint-filter", "Adaptive: an unsplit sample keeps its centre value (not the footprint mean of the texels)")(
      "sun", "Light strength", cxxopts::value<double>()->default_value("1"))(
      "env", "Constant environment (and background) radiance", cxxopts::value<double>()->default_value("0.25"))(
      "show-refined", "Write the refined pixels (white: 1 ray, grey: 3x3, black: 9x9) to this PNG",
      cxxopts::value<std::string>())(
      "compare", "Original stack to compare with the .nbtf <material>: writes reference/compressed/error images, "
                 "compare.md and compare.json into the -o folder",
      cxxopts::value<std::string>())(
      "also", "--compare: a second material (.nbtf or .gltf) rendered beside the first: also.png, also_error.png, "
              "compare_also.md, and side_by_side.png (stack | material | this)",
      cxxopts::value<std::string>())("magnify", "--compare: error image magnification",
                                     cxxopts::value<double>()->default_value("8"))(
      "reference", "EXR of the same scene to measure this render's RMSE against (in --stats-json)",
      cxxopts::value<std::string>())("ray-cost", "Measure a derivative ray's cost relative to a plain one (in --stats-json)")(
      "stats-json", "Write counts, times and RMSE as JSON", cxxopts::value<std::string>());
  addCropOption(options, " (a material given as an image stack)");
  return options;
}

// Sampling: adaptive (the default) or N x N uniform, from --uniform or --spp.
RenderOptions samplingOptions(const cxxopts::ParseResult& args, bool quiet) {
  RenderOptions ro;
  auto [w, h] = parseImageSize(args["size"].as<std::string>(), "--size", kMaxRenderSide);
  ro.width = w, ro.height = h;
  if (args.count("uniform") + args.count("spp") + args.count("adaptive") > 1)
    throw Error("give one of --adaptive, --uniform N and --spp N");
  if (args.count("uniform")) {
    ro.mode = SamplingMode::Uniform;
    ro.uniform = args["uniform"].as<int>();
  } else if (args.count("spp")) {
    const int spp = args["spp"].as<int>();
    const int n = static_cast<int>(std::lround(std::sqrt(std::max(0, spp))));
    if (spp < 1 || n * n != spp) throw Error("--spp must be a square number (1, 4, 9, 16, ...), got " + std::to_string(spp));
    ro.mode = SamplingMode::Uniform;
    ro.uniform = n;
  }
  ro.levels = args["levels"].as<int>();
  ro.threshold = args["threshold"].as<double>();
  ro.shadowCorners = !args.count("no-shadow-corners");
  ro.derivativeTests = !args.count("no-derivative-tests");
  ro.textureTest = !args.count("no-texture-test");
  ro.footprintFilter = !args.count("no-footprint-filter");
  ro.progress = !quiet;
  checkRenderOptions(ro);
  return ro;
}

// The paths the command reads and writes.
struct RenderPaths {
  std::string material, output, exr, mask, stats, stack, referenceExr, also;
};

// reference | compressed | also, side by side (linear RGB, the images' height).
std::vector<float> sideBySide(const std::vector<const RenderResult*>& images) {
  const int w = images[0]->width, h = images[0]->height, n = static_cast<int>(images.size());
  std::vector<float> out(static_cast<std::size_t>(w) * n * h * 3);
  for (int i = 0; i < n; ++i)
    for (int y = 0; y < h; ++y)
      std::copy_n(images[i]->rgb.data() + static_cast<std::size_t>(y) * w * 3, w * 3,
                  out.data() + (static_cast<std::size_t>(y) * w * n + static_cast<std::size_t>(i) * w) * 3);
  return out;
}

// --compare: the same scene rendered from the original stack and from the .nbtf, the images
// and their difference, compare.md and compare.json in the output folder.
int renderCompare(const cxxopts::ParseResult& args, const RenderPaths& p, const Scene& scene, const Camera& camera,
                     const RenderOptions& ro, const Crop& crop, bool quiet) {
  const std::string &material = p.material, &output = p.output, &stackPath = p.stack, &statsPath = p.stats;
  for (const char* o : {"exr", "show-refined", "reference", "ray-cost"})
    if (args.count(o)) throw Error(std::string("--") + o + " is for a single render, not --compare");
  if (std::filesystem::is_regular_file(stackPath) && hasNbtfMagic(stackPath))
    throw Error("--compare " + stackPath + ": expected the original image stack folder (the .nbtf or .gltf is the "
                "<material>: nbtf render --compare STACK FILE.nbtf -o DIR)");
  if (std::filesystem::is_directory(material))
    throw Error(material + ": with --compare the <material> is the .nbtf or .gltf file (nbtf render --compare STACK "
                "FILE.nbtf -o DIR)");
  std::unique_ptr<MaterialSource> reference = openMaterial(stackPath, crop, !quiet);
  std::unique_ptr<MaterialSource> compressed = openMaterial(material, {}, !quiet);
  checkCompareDirections(*reference, *compressed);
  checkFolderCreatable(output);
  createFolder(output);
  if (reference->width() != compressed->width() || reference->height() != compressed->height())
    std::cerr << "nbtf render: warning: " << stackPath << " is " << reference->width() << "x" << reference->height()
              << " texels, " << material << " is " << compressed->width() << "x" << compressed->height()
              << " (use --crop for the crop the .nbtf was made from)" << std::endl;
  const RenderResult ref = renderImage(scene, camera, *reference, ro);
  const RenderResult cmp = renderImage(scene, camera, *compressed, ro);
  const RenderComparison c = compareImages(ref.rgb, cmp.rgb, ref.coverage, ro.width, ro.height);
  std::unique_ptr<MaterialSource> also = p.also.empty() ? nullptr : openMaterial(p.also, {}, !quiet);
  CompareReportInfo info;
  info.reference = stackPath, info.compressed = material, info.scene = scene.name;
  info.width = ro.width, info.height = ro.height, info.sampling = samplingName(ro);
  info.magnify = args["magnify"].as<double>();
  info.referenceSeconds = ref.stats.seconds, info.compressedSeconds = cmp.stats.seconds;
  const std::filesystem::path dir(output);
  writeRender((dir / "reference.png").string(), (dir / "reference.exr").string(), ref);
  writeRender((dir / "compressed.png").string(), (dir / "compressed.exr").string(), cmp);
  const std::vector<float> err = errorImage(ref.rgb, cmp.rgb, info.magnify);
  writeImageSrgb8((dir / "error.png").string(), ImageFormat::Png, ro.width, ro.height, err.data());
  writeFileAtomic((dir / "compare.md").string(), compareMarkdown(c, info));
  writeFileAtomic((dir / "compare.json").string(), compareJson(c, info));
  if (also) {  // a second material (a glTF fit beside the .nbtf, say): its render, error and report
    const RenderResult second = renderImage(scene, camera, *also, ro);
    const RenderComparison c2 = compareImages(ref.rgb, second.rgb, ref.coverage, ro.width, ro.height);
    CompareReportInfo info2 = info;
    info2.compressed = p.also, info2.compressedSeconds = second.stats.seconds;
    writeRender((dir / "also.png").string(), (dir / "also.exr").string(), second);
    const std::vector<float> err2 = errorImage(ref.rgb, second.rgb, info.magnify);
    writeImageSrgb8((dir / "also_error.png").string(), ImageFormat::Png, ro.width, ro.height, err2.data());
    writeFileAtomic((dir / "compare_also.md").string(), compareMarkdown(c2, info2));
    writeFileAtomic((dir / "compare_also.json").string(), compareJson(c2, info2));
    const std::vector<float> row = sideBySide({&ref, &cmp, &second});
    writeImageSrgb8((dir / "side_by_side.png").string(), ImageFormat::Png, ro.width * 3, ro.height, row.data());
    std::cout << "render --compare: " << p.also << ": RMSE (linear) all " << c2.all.rmse << " -> "
              << (dir / "compare_also.md").string() << "; side_by_side.png: stack | " << material << " | " << p.also
              << std::endl;
  }
  if (!statsPath.empty()) {
    nlohmann::json j;
    j["reference"] = statsJson(ref, ro);
    j["compressed"] = statsJson(cmp, ro);
    writeFileAtomic(statsPath, j.dump(2) + "\n");
  }
  std::cout << "render --compare: " << scene.name << " " << ro.width << "x" << ro.height << ", RMSE (linear) all "
            << c.all.rmse << ", darkest 10% " << c.dark.rmse << ", brightest 10% " << c.bright.rmse << " -> "
            << (dir / "compare.md").string() << std::endl;
  return 0;
}

// One render of the material, with its optional EXR, refined-pixel mask, statistics and RMSE
// against a reference EXR.
int renderSingle(const cxxopts::ParseResult& args, const RenderPaths& p, const Scene& scene, const Camera& camera,
                 const RenderOptions& ro, const Crop& crop, bool quiet) {
  const std::string &material = p.material, &output = p.output, &exr = p.exr, &mask = p.mask, &statsPath = p.stats;
  for (const char* o : {"magnify"})
    if (args.count(o)) throw Error(std::string("--") + o + " is for --compare");
  imageFormatFromName(output);  // a clear error for an unknown extension, before rendering
  createParentFolders(output);
  checkWritable(output);
  if (!exr.empty()) checkWritable(exr);
  if (!mask.empty()) checkWritable(mask), imageFormatFromName(mask);
  if (!statsPath.empty()) checkWritable(statsPath);
  ImageF referenceImage;
  if (args.count("reference")) {
    referenceImage = readExr(args["reference"].as<std::string>());
    if (referenceImage.width != ro.width || referenceImage.height != ro.height)
      throw fileError(args["reference"].as<std::string>(),
                      "is " + std::to_string(referenceImage.width) + "x" + std::to_string(referenceImage.height) +
                          ", the render is " + std::to_string(ro.width) + "x" + std::to_string(ro.height));
  }
  std::unique_ptr<MaterialSource> source = openMaterial(material, crop, !quiet);
  const RenderResult r = renderImage(scene, camera, *source, ro);
  writeRender(output, exr, r);
  if (!mask.empty()) writeRefinedMask(mask, r);
  nlohmann::json j = statsJson(r, ro);
  j["material"] = material;
  j["scene"] = scene.name;
  if (args.count("ray-cost")) {
    const RayCost cost = measureRayCost(scene, camera, *source, ro);
    j["ray_cost"] = {{"samples", cost.samples}, {"plain_seconds", cost.plainSeconds},
                     {"derivative_seconds", cost.derivativeSeconds}, {"derivative_over_plain", cost.ratio}};
    j["ray_equivalents"] = double(r.stats.plainRays) + cost.ratio * double(r.stats.derivativeRays);
    j["ray_equivalents_per_pixel"] = j["ray_equivalents"].get<double>() / double(r.stats.pixels);
  }
  if (args.count("reference")) j["rmse_vs_reference"] = rmseOf(r.rgb.data(), referenceImage.rgb.data(), r.rgb.size());
  if (!statsPath.empty()) writeFileAtomic(statsPath, j.dump(2) + "\n");
  const RenderStats& s = r.stats;
  std::ostringstream o;
  o << "render: " << scene.name << " " << ro.width << "x" << ro.height << ", " << samplingName(ro) << ": ";
  if (ro.mode == SamplingMode::Adaptive)
    o << std::fixed << std::setprecision(1) << 100.0 * s.refinedPixels / s.pixels << "% of pixels refined ("
      << 100.0 * s.refinedTwice / s.pixels << "% twice), ";
  o << s.derivativeRays << " derivative + " << s.plainRays << " plain rays, " << std::fixed << std::setprecision(2)
    << s.seconds << " s -> " << output;
  if (j.contains("rmse_vs_reference")) o << "; RMSE vs reference " << std::setprecision(5) << j["rmse_vs_reference"].get<double>();
  std::cout << o.str() << std::endl;  // -q hides progress bars only, as in every command
  return 0;
}

}  // namespace

int renderMain(int argc, char** argv) {
  return runGuarded("render", [&] {
    cxxopts::Options options = renderOptions();
    cxxopts::ParseResult args;
    if (!parseCommand(options, "material", argc, argv, args)) return 0;
    const bool quiet = args.count("quiet") > 0;
    if (quiet) Progress::setQuiet(true);
    if (!args.count("material")) throw Error("missing <material> (a .nbtf file or an image stack folder; see 'nbtf render --help')");
    if (!args.count("output")) throw Error("missing -o (the output image; with --compare the output folder)");
    const bool compare = args.count("compare") > 0;
    const RenderOptions ro = samplingOptions(args, quiet);

    Scene scene = makeScene(args["scene"].as<std::string>(), args["tiling"].as<double>());
    setLight(scene, parseDirection(args["light"].as<std::string>(), "--light"));
    scene.sun = args["sun"].as<double>();
    scene.env = args["env"].as<double>();
    if (!(scene.sun >= 0) || !(scene.env >= 0) || !std::isfinite(scene.sun) || !std::isfinite(scene.env))
      throw Error("--sun and --env must be numbers >= 0");
    CameraSpec cam = scene.camera;
    if (args.count("camera")) cam = parseCamera(args["camera"].as<std::string>(), scene.camera, "--camera");
    const Camera camera(cam, ro.width, ro.height);
    const Crop crop = cropOption(args).value_or(Crop{});

    auto optional = [&](const char* name) { return args.count(name) ? args[name].as<std::string>() : std::string(); };
    RenderPaths p;
    p.material = args["material"].as<std::string>();
    p.output = args["output"].as<std::string>();
    p.exr = optional("exr");
    p.mask = optional("show-refined");
    p.stats = optional("stats-json");
    p.stack = optional("compare");
    p.referenceExr = optional("reference");
    p.also = optional("also");
    if (!p.also.empty() && !compare) throw Error("--also is for --compare (a second material rendered beside the first)");
    // No output may overwrite an input or another output; then every output's folders are made.
    refuseOverlappingPaths({{"<material>", p.material},
                            {"--compare", p.stack},
                            {"--reference", p.referenceExr},
                            {"--also", p.also}},
                           {{"-o", p.output, compare}, {"--exr", p.exr}, {"--show-refined", p.mask}, {"--stats-json", p.stats}});
    for (const std::string& out : {p.exr, p.mask, p.stats})
      if (!out.empty()) createParentFolders(out);
    return compare ? renderCompare(args, p, scene, camera, ro, crop, quiet)
                   : renderSingle(args, p, scene, camera, ro, crop, quiet);
  });
}

}  // namespace nbtf::cli
