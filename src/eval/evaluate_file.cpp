#include "eval/evaluate_file.h"

#include <cstdio>
#include <filesystem>

#include "codec/nbtf_file.h"
#include "eval/compressed_source.h"
#include "gltf/gltf_read.h"
#include "io/btf_loader.h"
#include "io/ground_truth.h"
#include "io/source_fingerprint.h"
#include "util/error.h"

namespace nbtf {
namespace {

std::string rgbText(const std::array<double, 3>& m) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.4g, %.4g, %.4g)", m[0], m[1], m[2]);
  return buf;
}

}  // namespace

std::string checkReferenceFingerprint(const CompressedBtf& btf, const BtfStack& reference, const std::string& file,
                                      const std::string& referencePath, bool force, const std::string& program) {
  std::optional<SourceFingerprint> stored = sourceFingerprintOf(btf.metadataJson, file);
  if (!stored) {
    std::fprintf(stderr,
                 "%s: warning: %s has no source fingerprint (made by an older nbtf): cannot check that '%s' "
                 "is the material it was made from\n",
                 program.c_str(), file.c_str(), referencePath.c_str());
    return "not checked: the file has no source fingerprint (made by an older nbtf)";
  }
  FingerprintCheck c = checkSourceFingerprint(*stored, reference);
  char pct[32], pattern[160];
  std::snprintf(pct, sizeof pct, "%.1f%%", 100 * c.medianDifference);
  std::snprintf(pattern, sizeof pattern,
                c.patternDifference >= 0 ? "texel pattern difference %.3f (tolerance 0.1)" : "texel pattern not compared",
                c.patternDifference);
  if (c.matches)
    return std::string("matches the file's source fingerprint (median difference ") + pct + ", " + pattern + ")";
  std::string what = "reference '" + referencePath + "' is not the material '" + file + "' was made from: ";
  std::string summary;
  if (c.medianDifference > 0.1 || c.patternMatches) {
    const Direction& l = reference.lights()[c.worstImage / reference.numViews()];
    const Direction& v = reference.views()[c.worstImage % reference.numViews()];
    what += "per-image mean linear RGB differs by " + std::string(pct) + " (median over " +
            std::to_string(stored->images.size()) + " images, tolerance 10%); image " + std::to_string(c.worstImage) +
            " (light " + formatDirection(l) + ", view " + formatDirection(v) + ") has " + rgbText(c.measured) +
            " in the reference, " + rgbText(c.stored) + " in the source";
    summary = std::string("per-image mean linear RGB differs by ") + pct + " (median)";
  } else {
    // The same kind of material, another piece of it: the means agree, the texels do not.
    what += std::string("the means agree (median difference ") + pct + ") but the texels do not: " + pattern +
            "; the RMS difference of the median luminance at " + std::to_string(stored->pattern.size()) +
            " sampled texels, over the source's spread (another capture of the same kind of material?)";
    summary = std::string(pattern);
  }
  if (!force) throw Error(what + " (--force uses it anyway)");
  std::fprintf(stderr, "%s: warning: %s; using it anyway (--force)\n", program.c_str(), what.c_str());
  return "MISMATCH, used anyway (--force): " + summary + " from the file's source";
}

namespace {

// A glTF fit (nbtf export-gltf, or any core metallic-roughness material of the stack's size) as
// the compressed material: its textures' values at every measured pair, its PNG bytes.
EvaluateFileResult evaluateGltf(const std::string& file, const std::string& referencePath,
                                const EvaluateFileOptions& options, RenderSection render) {
  const gltf::GltfMaterial material = gltf::readGltfMaterial(file);
  LoadOptions load;
  load.progress = options.eval.progress;
  if (options.crop) load.crop = *options.crop;
  if (options.layout) load.layout = *options.layout;
  BtfStack reference = loadBtfStack(referencePath, load);
  if (reference.width() != material.width || reference.height() != material.height)
    throw Error(file + ": its textures are " + std::to_string(material.width) + " x " + std::to_string(material.height) +
                ", the reference '" + referencePath + "' is " + std::to_string(reference.width()) + " x " +
                std::to_string(reference.height()) + " texels (--crop cuts the reference)");
  EvalInputs inputs;
  inputs.reference = &reference;
  const std::vector<Direction> lights = reference.lights(), views = reference.views();
  inputs.reconstruct = [&material, lights, views](int image, float* rgb) {
    const auto l = lights[image / views.size()].unitVector(), v = views[image % views.size()].unitVector();
    const gltf::Vec3 lu{l[0], l[1], l[2]}, vu{v[0], v[1], v[2]};
    for (std::size_t t = 0; t < material.texels.size(); ++t) {
      const gltf::Vec3 value = material.value(static_cast<int>(t), lu, vu);
      for (int c = 0; c < 3; ++c) rgb[3 * t + c] = static_cast<float>(value[c]);
    }
  };
  inputs.sizes.gltf = true;
  inputs.sizes.rawFloat32 = reference.rawFloat32Bytes();
  inputs.sizes.textures = gltf::textureFileBytes(file);
  inputs.sizes.total = inputs.sizes.textures;
  inputs.method = std::string("glTF 2.0 metallic-roughness fit") + (material.sheen ? " with sheen" : "");
  inputs.methodFamily = "gltf";
  inputs.referenceName = referencePath;
  inputs.compressedName = file;
  inputs.details.push_back({"exposure (sun strength)", std::to_string(material.exposure)});
  if (options.groundTruth) inputs.groundTruth = groundTruthBeside(referencePath, reference, load.crop);
  if (inputs.groundTruth) inputs.groundTruthName = (std::filesystem::path(referencePath) / kGroundTruthFolder).string();
  EvaluateFileResult out;
  out.result = evaluate(inputs, options.eval);
  out.result.render = std::move(render);
  out.evaluationsPerImage = static_cast<int>(material.texels.size());
  return out;
}

}  // namespace

EvaluateFileResult evaluateFile(const std::string& file, const std::string& referencePath,
                                const EvaluateFileOptions& options) {
  RenderSection render;
  if (!options.renderCompare.empty()) render = loadRenderSection(options.renderCompare);
  if (gltf::isGltfPath(file)) return evaluateGltf(file, referencePath, options, std::move(render));

  CompressedBtf btf = readNbtf(file);
  std::uint64_t fileBytes = std::filesystem::file_size(file);

  // The reference, cut the way the file was made unless told otherwise.
  LoadOptions load;
  load.progress = options.eval.progress;
  load.crop = options.crop.value_or(btf.crop);
  // The file's layout names a folder's files; a UBO2014 file's reference may be its .btf or a
  // folder it was decoded to, whose layout is found from its names.
  load.layout = options.layout.value_or(btf.layout == Layout::Ubo2014 ? Layout::Unknown : btf.layout);
  BtfStack reference = loadBtfStack(referencePath, load);
  checkReferenceMatches(btf, reference, file, referencePath);
  const std::string referenceCheck =
      checkReferenceFingerprint(btf, reference, file, referencePath, options.force, "nbtf eval");

  CompressedReconstruction reconstruction(btf, file);
  EvalInputs inputs = compressedEvalInputs(btf, reference, reconstruction, file, referencePath, fileBytes);
  inputs.details.push_back({"reference check", referenceCheck});
  if (options.groundTruth) inputs.groundTruth = groundTruthBeside(referencePath, reference, load.crop);
  if (inputs.groundTruth) inputs.groundTruthName = (std::filesystem::path(referencePath) / kGroundTruthFolder).string();
  EvaluateFileResult out;
  out.result = evaluate(inputs, options.eval);
  out.result.render = std::move(render);
  out.evaluationsPerImage = reconstruction.evaluationsPerImage();
  return out;
}

}  // namespace nbtf
