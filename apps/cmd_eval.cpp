// nbtf eval <file.nbtf> --reference <stack> -o <dir>: decode every image of a compressed
// material, compare it with the measured reference, and write report.md / .html / .json.
#include <cstdio>
#include <filesystem>

#include "cli_common.h"
#include "commands.h"
#include "eval/evaluate_file.h"
#include "eval/report.h"
#include "eval/sweep.h"
#include "util/progress.h"

namespace nbtf::cli {
namespace {

// --summarize: many report.json files -> sweep tables and rate-distortion plots.
int runSummarize(const cxxopts::ParseResult& args) {
  if (!args.count("output")) throw Error("missing -o <folder> for the sweep summary (see 'nbtf eval --help')");
  if (!args.count("files")) throw Error("--summarize needs report.json files");
  std::vector<PathUse> reports;
  for (const auto& path : args["files"].as<std::vector<std::string>>()) reports.push_back({"report", path});
  refuseOverlappingPaths(reports, {{"-o", args["output"].as<std::string>(), true}});
  std::vector<SweepEntry> entries;
  for (const auto& report : reports) entries.push_back(readSweepEntry(report.path));
  SweepFiles files = writeSweepSummary(entries, args["output"].as<std::string>());
  std::printf("%s", sweepTablesMarkdown(entries).c_str());
  std::printf("table           %s\n", files.table.c_str());
  for (const auto& plot : files.plots) std::printf("plot            %s\n", plot.c_str());
  return 0;
}

int runEval(const cxxopts::ParseResult& args) {
  if (args.count("summarize")) return runSummarize(args);
  if (!args.count("files")) throw Error("missing <file.nbtf> (see 'nbtf eval --help')");
  const auto& files = args["files"].as<std::vector<std::string>>();
  if (files.size() != 1) throw Error("expected one <file.nbtf>, got " + std::to_string(files.size()));
  if (!args.count("reference")) throw Error("missing --reference <stack folder> (see 'nbtf eval --help')");
  if (!args.count("output")) throw Error("missing -o <report folder> (see 'nbtf eval --help')");
  const std::string file = files.front();
  const std::string referencePath = args["reference"].as<std::string>();
  const std::string outDir = args["output"].as<std::string>();
  EvalOptions options;
  options.blurSampleImages = args["blur-images"].as<int>();
  if (options.blurSampleImages < 0) throw Error("--blur-images must be >= 0");
  options.progress = !args.count("quiet");

  // Fail on an unwritable output, or one that would overwrite an input, before decoding
  // anything; the folder (and its missing parents) is made when the report is written.
  refuseOverlappingPaths({{"<file.nbtf>", file},
                          {"--reference", referencePath},
                          {"--render-compare", args.count("render-compare") ? args["render-compare"].as<std::string>() : ""}},
                         {{"-o", outDir, true}});
  checkFolderCreatable(outDir);
  EvaluateFileOptions fileOptions;
  fileOptions.eval = options;
  fileOptions.crop = cropOption(args);
  fileOptions.layout = layoutOption(args);
  fileOptions.force = args.count("force") > 0;
  fileOptions.groundTruth = !args.count("no-ground-truth");
  if (args.count("render-compare")) fileOptions.renderCompare = args["render-compare"].as<std::string>();
  EvaluateFileResult run = evaluateFile(file, referencePath, fileOptions);
  const EvalResult& result = run.result;
  ReportPaths paths = writeReport(result, outDir);

  std::printf("method          %s (%d decoder evaluations per image)\n", result.method.c_str(),
              run.evaluationsPerImage);
  std::printf("RMSE            %.5f (linear RGB / alpha, eq. 10), %.3f (sRGB 8-bit codes)\n", result.all.rmse,
              result.all.rmseSrgb8);
  std::printf("PSNR            %.2f dB (linear / alpha, peak 1), %.2f dB (sRGB 8-bit, peak 255)\n", result.all.psnr,
              result.all.psnrSrgb8);
  if (result.hasHoldout())
    std::printf("held-out RMSE   %.5f (linear RGB / alpha) over %zu images; training %.5f\n", result.holdout.rmse,
                result.holdoutImages.size(), result.training.rmse);
  else
    std::printf("held-out RMSE   none (the file records no held-out images)\n");
  if (result.hasGroundTruth) {
    std::printf("vs truth RMSE   %.5f all images", result.groundTruthAll.rmse);
    if (result.hasHoldout()) std::printf(", %.5f held out", result.groundTruthHoldout.rmse);
    std::printf(" (linear RGB / alpha, against the float ground truth)\n");
    std::printf("noise floor     %.5f: the %s stack against the ground truth (%s)\n", result.referenceVsGroundTruth.rmse,
                result.referenceEncoding.c_str(), result.noiseFloorCause.c_str());
  }
  std::printf("ratio           1 : %.0f (raw float32 / total)\n", result.sizes.ratio());
  int atBound = 0;
  for (const auto& s : result.blurSamples) atBound += s.estimate.atUpperBound;
  std::printf("blur sigma      %.3f texels (median of %zu images%s)\n", result.blurSigmaMedian, result.blurSamples.size(),
              atBound ? (", " + std::to_string(atBound) + " at the upper bound: no detail left").c_str() : "");
  std::printf("time            %.1f s\n", result.seconds);
  std::printf("report          %s\n                %s\n                %s\n", paths.html.c_str(), paths.markdown.c_str(),
              paths.json.c_str());
  return 0;
}

}  // namespace

int evalMain(int argc, char** argv) {
  return runGuarded("eval", [&] {
    cxxopts::Options options("nbtf eval", "Compare a compressed material with its reference; write an RMSE report");
    options.positional_help("<file.nbtf or material.gltf> --reference <stack> -o <report folder>  |  --summarize -o <folder> <report.json>...");
    options.add_options()("files", "Compressed material (.nbtf); with --summarize: report.json files",
                          cxxopts::value<std::vector<std::string>>())(
        "r,reference", "The measured BTF image stack it was made from", cxxopts::value<std::string>())(
        "o,output", "Report folder (created if missing)", cxxopts::value<std::string>())(
        "blur-images", "Evenly spaced images for the blur estimate (besides the compared ones)",
        cxxopts::value<int>()->default_value("8"))(
        "force", "Evaluate even when the reference does not match the file's source fingerprint (the report says so)")(
        "no-ground-truth", "Do not also measure against the float ground truth beside the reference (nbtf-synth's "
                           "ground_truth/ folder; read by default when present)")(
        "render-compare", "Include a rendered comparison: the folder `nbtf render --compare` wrote",
        cxxopts::value<std::string>())(
        "summarize", "Sweep mode: summarize report.json files into -o (tables, rate-distortion plots)");
    addCropOption(options, " (default: the file's crop)");
    addLayoutOption(options, " (default: the file's)");
    cxxopts::ParseResult args;
    if (!parseCommand(options, "files", argc, argv, args)) return 0;
    return runEval(args);
  });
}

}  // namespace nbtf::cli
