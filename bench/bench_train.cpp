// nbtf-bench-train: the numbers behind scripts/bench_train.sh.
//   --matmul                 libtorch float32 mm rate (n x n, all threads)
//   --throughput             training throughput on an in-memory material (k clusters, N images)
//   --converge DIR           the whole pipeline on a stack on disk (preprocess, k-means, train),
//                            training with the config, then again with `--long-factor` x the epochs
// Every figure is printed as "key value" lines for the script to pick up.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>

#include "cluster/clustering.h"
#include "io/btf_loader.h"
#include "support/torch_reference.h"
#include "model/trainer.h"
#include "pipeline/compress_config.h"
#include "preprocess/abrdf_matrix.h"
#include "preprocess/abrdf_source.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/timer.h"

using namespace nbtf;

namespace {


// A smooth analytic material (diffuse x cos + a glossy lobe, per-texel albedo), for
// throughput only: the cost of a training step does not depend on the values.
BtfStack analyticStack(int size, int directionsPerAxis) {
  const auto& h81 = hemisphere81();
  std::vector<Direction> dirs;
  for (int i = 0; i < directionsPerAxis; ++i) dirs.push_back(h81[i * 81 / directionsPerAxis]);
  BtfStack stack(dirs, dirs, size, size, SampleType::Srgb8);
  const int M = size * size;
  parallelFor(stack.numImages(), [&](std::size_t begin, std::size_t end) {
    std::vector<float> rgb(static_cast<std::size_t>(M) * 3);
    for (std::size_t img = begin; img < end; ++img) {
      auto l = dirs[img / stack.numViews()].unitVector();
      auto v = dirs[img % stack.numViews()].unitVector();
      double lobe = std::pow(std::max(0.0, -l[0] * v[0] - l[1] * v[1] + l[2] * v[2]), 8.0);
      for (int t = 0; t < M; ++t) {
        double a = 0.3 + 0.25 * std::sin(0.11 * t), g = 0.5 + 0.4 * std::cos(0.07 * t);
        for (int c = 0; c < 3; ++c) rgb[3 * t + c] = static_cast<float>((a + 0.1 * c) * l[2] * 0.8 + g * lobe * 0.5);
      }
      stack.setImageLinear(static_cast<int>(img), rgb.data());
    }
  });
  return stack;
}

// Reference RMSEs (linear / alpha, over texels x images x channels): predicting each
// image's mean colour, and replacing every texel by its cluster's mean ABRDF (the floor of
// any model with one latent per cluster).
void printReferenceRmse(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids, int k) {
  const int M = stack.numTexels(), N = stack.numImages();
  std::vector<double> sse(N, 0.0), sseCluster(N, 0.0);
  parallelFor(N, [&](std::size_t begin, std::size_t end) {
    std::vector<float> rgb(static_cast<std::size_t>(M) * 3);
    std::vector<double> sum(static_cast<std::size_t>(std::max(k, 1)) * 3), count(std::max(k, 1));
    for (std::size_t i = begin; i < end; ++i) {
      stack.imageLinear(static_cast<int>(i), rgb.data());
      for (auto& v : rgb) v /= alpha;
      double mean[3] = {0, 0, 0};
      for (int t = 0; t < M; ++t)
        for (int c = 0; c < 3; ++c) mean[c] += rgb[3 * t + c];
      for (int t = 0; t < M; ++t)
        for (int c = 0; c < 3; ++c) sse[i] += std::pow(rgb[3 * t + c] - mean[c] / M, 2);
      if (ids.empty()) continue;
      std::fill(sum.begin(), sum.end(), 0.0);
      std::fill(count.begin(), count.end(), 0.0);
      for (int t = 0; t < M; ++t) {
        count[ids[t]] += 1;
        for (int c = 0; c < 3; ++c) sum[3 * ids[t] + c] += rgb[3 * t + c];
      }
      for (int t = 0; t < M; ++t)
        for (int c = 0; c < 3; ++c) sseCluster[i] += std::pow(rgb[3 * t + c] - sum[3 * ids[t] + c] / count[ids[t]], 2);
    }
  });
  double a = 0, b = 0;
  for (int i = 0; i < N; ++i) a += sse[i], b += sseCluster[i];
  std::printf("reference_rmse_image_mean %.6f\n", std::sqrt(a / (3.0 * M * N)));
  if (!ids.empty()) std::printf("reference_rmse_cluster_mean %.6f\n", std::sqrt(b / (3.0 * M * N)));
}

void printResult(const std::string& prefix, const TrainResult& r) {
  std::printf("%s_rmse_train %.6f\n", prefix.c_str(), r.rmseTrain);
  std::printf("%s_rmse_holdout %.6f\n", prefix.c_str(), r.rmseHoldout);
  std::printf("%s_seconds %.2f\n", prefix.c_str(), r.seconds);
  std::printf("%s_train_seconds %.2f\n", prefix.c_str(), r.trainSeconds);
  std::printf("%s_epochs %d\n", prefix.c_str(), r.epochsRun);
  std::printf("%s_steps %lld\n", prefix.c_str(), static_cast<long long>(r.steps));
  std::printf("%s_samples_per_second %.0f\n", prefix.c_str(), r.samplesPerSecond);
  std::printf("%s_decoder_gflops %.2f\n", prefix.c_str(), r.decoderGflops);
  std::printf("%s_profile_seconds sampling %.2f encoder %.2f decoder %.2f optimizer %.2f\n", prefix.c_str(),
              r.profile.sampling, r.profile.encoder, r.profile.decoder, r.profile.optimizer);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  cxxopts::Options options("nbtf-bench-train", "Training benchmarks (see scripts/bench_train.sh)");
  options.add_options()("matmul", "Measure libtorch mm rate")("n", "Matrix size for --matmul",
                                                             cxxopts::value<int>()->default_value("2048"))(
      "throughput", "Measure training throughput on an in-memory material")(
      "converge", "Pipeline + training on this stack folder", cxxopts::value<std::string>())(
      "config", "Training config", cxxopts::value<std::string>())(
      "clusters", "k (0 = per-texel)", cxxopts::value<int>()->default_value("500"))(
      "size", "Texels per side (--throughput)", cxxopts::value<int>()->default_value("100"))(
      "directions", "Directions per axis (--throughput)", cxxopts::value<int>()->default_value("81"))(
      "seconds", "Training time for --throughput", cxxopts::value<double>()->default_value("30"))(
      "epochs", "Override the config's epochs", cxxopts::value<int>())(
      "long-factor", "--converge: also train this many times as long (0 = skip)",
      cxxopts::value<int>()->default_value("4"))("threads", "Threads (0 = all)",
                                                  cxxopts::value<int>()->default_value("0"))(
      "decoder-only", "Measure the decoder's training pass alone")(
      "steps", "Steps for --decoder-only", cxxopts::value<int>()->default_value("40"))(
      "crop", "--converge: crop X,Y,W,H", cxxopts::value<std::string>())(
      "cluster-space", "--converge: log or linear (default: the config's clustering.space, else nbtf compress's)",
      cxxopts::value<std::string>())(
      "trace", "Print the training's course every this many seconds (0 = off)",
      cxxopts::value<double>()->default_value("0"))(
      "progress", "Show progress bars")("h,help", "Help");
  try {
    auto args = options.parse(argc, argv);
    if (args.count("help")) {
      std::cout << options.help() << std::endl;
      return 0;
    }
    setThreadCount(args["threads"].as<int>());
    const int threads = threadCount();
    const bool progress = args.count("progress") > 0;
    std::printf("threads %d\n", threads);
    std::setvbuf(stdout, nullptr, _IOLBF, 0);  // line-buffered: scripts see figures as they come
    if (args.count("matmul")) {
      int n = args["n"].as<int>();
      std::printf("matmul_n %d\nmatmul_gflops %.2f\n", n, matmulGflops(n, threads, 3.0));
    }
    if (args.count("decoder-only")) {
      // The decoder's training pass alone, at the configured step geometry.
      TrainConfig c = args.count("config") ? loadTrainConfig(args["config"].as<std::string>()) : TrainConfig{};
      int tiles = std::max(1, c.batchSize / c.imagesPerInput);
      DecoderStepRate r = decoderStepRate(c.model, tiles, c.imagesPerInput, args["steps"].as<int>(), threads,
                                          resolvedProducts(c) == "bf16");
      double flops = decoderShape(c.model).flopsPerSample() * 3;
      std::printf("decoder_only_samples_per_second %.0f\ndecoder_only_gflops %.2f\ndecoder_only_cpu_gflops_per_thread %.2f\n",
                  r.samplesPerSecond, r.samplesPerSecond * flops / 1e9,
                  r.samplesPerSecond * r.wallSeconds / r.cpuSeconds * flops / 1e9);
    }
    TrainConfig config;
    if (args.count("config")) config = loadTrainConfig(args["config"].as<std::string>());
    if (args.count("epochs")) config.epochs = args["epochs"].as<int>(), config.minSteps = config.minStepsPerInput = config.maxSteps = 0;
    config.threads = threads;
    config.progress = progress;
    const double traceEvery = args["trace"].as<double>();
    double nextTrace = 0;
    if (traceEvery > 0)
      config.monitor = [&](const TrainStatus& s) {
        if (s.seconds < nextTrace) return;
        nextTrace = s.seconds + traceEvery;
        std::printf("trace step %lld seconds %.1f loss %.4e rmse_est %.5f lr %.2e samples_per_second %.0f%s\n",
                    static_cast<long long>(s.step), s.seconds, s.loss, s.rmseEstimate, s.learningRate,
                    s.samplesPerSecond, s.polish ? " polish" : "");
        std::fflush(stdout);
      };
    const int k = args["clusters"].as<int>();

    if (args.count("throughput")) {
      auto t0 = Clock::now();
      BtfStack stack = analyticStack(args["size"].as<int>(), args["directions"].as<int>());
      MatrixXfCol x = abrdfMatrix(stack, progress);
      standardizeInPlace(x);
      TrainInputs in;
      in.stack = &stack;
      in.alpha = targetAlpha(stack);
      MatrixXfCol reps;
      if (k > 0) {
        // Any assignment will do for timing: texel t -> t mod k.
        in.ids.resize(stack.numTexels());
        for (int t = 0; t < stack.numTexels(); ++t) in.ids[t] = t % k;
        reps = clusterRepresentatives(x, in.ids, k, Representative::Mean);
        in.encoderInputs = &reps;
      } else {
        in.encoderInputs = &x;
      }
      std::printf("throughput_setup_seconds %.2f\n", secondsSince(t0));
      config.epochs = 0;
      config.timeBudgetSeconds = args["seconds"].as<double>();
      TrainResult r = trainModel(in, config);
      printResult("throughput", r);
    }

    if (args.count("converge")) {
      const std::string dir = args["converge"].as<std::string>();
      auto t0 = Clock::now();
      LoadOptions lo;
      lo.progress = progress;
      if (args.count("crop")) lo.crop = parseCrop(args["crop"].as<std::string>());
      BtfStack stack = loadBtfStack(dir, lo);
      std::printf("converge_texels %d\nconverge_images %d\n", stack.numTexels(), stack.numImages());
      std::printf("converge_load_seconds %.2f\n", secondsSince(t0));
      t0 = Clock::now();
      // The clusters are found where `nbtf compress` finds them (docs/clustering.md, *Clustering space*).
      const ClusteringSpace space =
          args.count("cluster-space")
              ? parseClusteringSpace(args["cluster-space"].as<std::string>(), "--cluster-space")
              : (args.count("config") ? loadCompressConfig(args["config"].as<std::string>()).clusteringSpace
                                      : kDefaultClusteringSpace);
      std::printf("converge_cluster_space %s\n", clusteringSpaceName(space));
      MatrixXfCol x = abrdfMatrix(stack, progress);
      TrainInputs in;
      in.stack = &stack;
      in.alpha = targetAlpha(stack);
      standardizeInPlace(x);
      std::printf("converge_preprocess_seconds %.2f\n", secondsSince(t0));
      ClusteringResult clusters;
      if (k > 0) {
        t0 = Clock::now();
        ClusteringOptions co;
        co.clusters = k;
        co.progress = progress;
        // The linear space streamed from the stack: no second copy of X.
        clusters = clusterAbrdfs(DenseAbrdfSource(x), co, clusteringSpaceSource(stack, space, in.alpha).get());
        std::printf("converge_cluster_seconds %.2f\n", secondsSince(t0));
        in.ids = clusters.ids;
        in.encoderInputs = &clusters.representatives;
      } else {
        in.encoderInputs = &x;
      }
      printReferenceRmse(stack, in.alpha, in.ids, k);
      TrainResult r = trainModel(in, config);
      printResult("converge", r);
      int factor = args["long-factor"].as<int>();
      if (factor > 0) {
        TrainConfig longer = config;
        longer.epochs = config.epochs * factor;
        longer.minSteps = config.minSteps * factor, longer.maxSteps = config.maxSteps * factor;
        longer.minStepsPerInput = config.minStepsPerInput * factor;
        if (config.timeBudgetSeconds > 0) longer.timeBudgetSeconds = config.timeBudgetSeconds * factor;
        TrainResult rl = trainModel(in, longer);
        printResult("long", rl);
        std::printf("long_factor %d\n", factor);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "nbtf-bench-train: error: %s\n", userMessage(e).c_str());
    return 1;
  }
  return 0;
}
