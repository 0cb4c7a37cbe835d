// Decoding benchmark, driven by scripts/bench_decode.sh.
//
// Two materials of the paper's setup, 100 x 100 texels, 81 x 81 directions, decoder
// 12 -> 106 -> 106 -> 106 -> 3 (ReLU): clustered with k = 500 latents + id list, and
// per-texel with 10,000 latents. Their weights, latents and ids are random (seeded):
// decoding speed depends on the shapes only, never on the values (no data-dependent
// branches; ReLU is a select). In one run, side by side:
//   - seconds to reconstruct all 6561 images in memory (8-bit sRGB BtfStack) and as PNG
//     files (the layout `nbtf decode` writes), clustered vs per-texel;
//   - batched query throughput (random texels and continuous random directions);
//   - what the direction inputs cost: clustered random-weight files with the paper's
//     stereographic inputs and with the default's stereographic + Fourier ones;
//   - the machine's float matmul rate, 2048^2 x 2048^2 on all threads, by Eigen (this
//     build's flags, blocks of columns on threadCount() threads) and by libtorch mm (its
//     BLAS); the faster of the two is the reference.
// Prints one "result KEY VALUE" line per figure for the script to check.
#include <torch/torch.h>

#include <Eigen/Core>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "codec/decoder.h"
#include "pipeline/decoder_output.h"
#include "codec/nbtf_file.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace {
using namespace nbtf;


template <class F> double bestOf(int runs, F&& f) {
  double best = 1e300;
  for (int i = 0; i < runs; ++i) {
    auto t = Clock::now();
    f();
    best = std::min(best, secondsSince(t));
  }
  return best;
}

CompressedBtf makeMaterial(bool clustered, unsigned seed,
                           DirectionEncoding directions = DirectionEncoding::Stereographic) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  CompressedBtf b;
  b.method = clustered ? CodecMethod::ClusteredNeural : CodecMethod::PerTexelNeural;
  b.width = b.height = 100;
  b.sourceWidth = b.sourceHeight = 256;
  b.crop = Crop{78, 78, 100, 100};
  b.layout = Layout::Ubo2003;
  b.sourceSampleType = SampleType::Srgb8;
  b.lights = b.views = hemisphere81();
  b.alpha = 1.0f;
  b.latentDim = 8;
  b.directionEncoding = directions;
  int in = b.latentDim + directionInputCount(directions);
  for (int i = 0; i < 4; ++i) {
    DenseLayer l;
    l.in = in, l.out = i < 3 ? 106 : 3;
    l.activation = i < 3 ? Activation::Relu : Activation::None;
    float scale = std::sqrt(2.0f / l.in);
    for (int j = 0; j < l.in * l.out; ++j) l.weight.push_back(scale * normal(rng));
    for (int j = 0; j < l.out; ++j) l.bias.push_back(0.1f * normal(rng));
    b.decoder.layers.push_back(l);
    in = l.out;
  }
  b.latentRows = clustered ? 500 : 10000;
  for (int i = 0; i < b.latentRows * b.latentDim; ++i) b.latents.push_back(normal(rng));
  if (clustered) {
    std::uniform_int_distribution<int> id(0, 499);
    for (int t = 0; t < 10000; ++t) b.ids.push_back(t < 500 ? t : id(rng));
  }
  return b;
}

double eigenGemmGflops(int n, int runs) {
  Eigen::MatrixXf a = Eigen::MatrixXf::Random(n, n), b = Eigen::MatrixXf::Random(n, n), c(n, n);
  const int blocks = threadCount();
  auto gemm = [&] {
    parallelFor(static_cast<std::size_t>(blocks), [&](std::size_t b0, std::size_t b1) {
      for (std::size_t k = b0; k < b1; ++k) {
        Eigen::Index c0 = n * static_cast<Eigen::Index>(k) / blocks, c1 = n * static_cast<Eigen::Index>(k + 1) / blocks;
        c.middleCols(c0, c1 - c0).noalias() = a * b.middleCols(c0, c1 - c0);
      }
    });
  };
  gemm();
  return 2.0 * n * n * double(n) / bestOf(runs, gemm) / 1e9;
}

double torchGemmGflops(int n, int runs) {
  torch::NoGradGuard noGrad;
  torch::set_num_threads(threadCount());
  auto a = torch::rand({n, n}), b = torch::rand({n, n});
  auto c = torch::mm(a, b);
  return 2.0 * n * n * double(n) / bestOf(runs, [&] { c = torch::mm(a, b); }) / 1e9;
}

std::vector<TexelQuery> randomQueries(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> texel(0, 99);
  std::uniform_real_distribution<double> theta(0, 90), phi(0, 360);
  std::vector<TexelQuery> q(n);
  for (auto& x : q) x = {texel(rng), texel(rng), {theta(rng), phi(rng)}, {theta(rng), phi(rng)}};
  return q;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_decode <work folder> [--quick] [--files CLUSTERED.nbtf PER_TEXEL.nbtf]\n");
    return 2;
  }
  namespace fs = std::filesystem;
  const fs::path work = argv[1];
  bool quick = false;
  std::string clusteredPath = (work / "clustered_k500.nbtf").string();
  std::string perTexelPath = (work / "per_texel.nbtf").string();
  bool given = false;
  for (int a = 2; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "--files" && a + 2 < argc) {
      clusteredPath = argv[++a], perTexelPath = argv[++a], given = true;
    } else {
      std::fprintf(stderr, "bench_decode: unknown argument '%s'\n", arg.c_str());
      return 2;
    }
  }
  fs::create_directories(work);
  Progress::setQuiet(true);
  std::printf("threads %d\n", threadCount());

  // The two files: really compressed ones (--files), or files of the paper's shapes with
  // random weights, written and opened the way `nbtf decode` opens them.
  if (!given) {
    writeNbtf(clusteredPath, makeMaterial(true, 1));
    writeNbtf(perTexelPath, makeMaterial(false, 1));
  }
  std::printf("files %s %s (%s)\n", clusteredPath.c_str(), perTexelPath.c_str(),
              given ? "compressed by nbtf compress" : "random weights, paper shapes");
  NbtfDecoder clustered = NbtfDecoder::open(clusteredPath);
  NbtfDecoder perTexel = NbtfDecoder::open(perTexelPath);
  std::printf("decoder kernels %s; %.0f FLOPs per evaluation (%s inputs, multiply-add = 2)\n",
              decoderIsaName(clustered.isa()).c_str(), clustered.flopsPerEvaluation(),
              directionEncodingName(clustered.directionEncoding()).c_str());

  // Optional subset for a smoke run.
  std::vector<DirectionChoice> lights;
  if (quick) lights = parseDirectionList("0-7", clustered.lights(), "--lights");
  const int images = (quick ? 8 : 81) * 81;

  // ---- Matmul reference (before and after the decoder runs; the best counts)
  double eigen = eigenGemmGflops(2048, 3), torchRate = torchGemmGflops(2048, 3);
  std::printf("matmul 2048^2 float: Eigen %.1f GFLOP/s, libtorch mm %.1f GFLOP/s\n", eigen, torchRate);

  // ---- Full reconstruction in memory (8-bit sRGB, like the source)
  double memClustered = bestOf(3, [&] { decodeStack(clustered, SampleType::Srgb8, lights, {}, false); });
  std::printf("in memory: clustered %d images %.3f s (%.0f images/s)\n", images, memClustered, images / memClustered);
  double memPerTexel = bestOf(quick ? 1 : 2, [&] { decodeStack(perTexel, SampleType::Srgb8, lights, {}, false); });
  std::printf("in memory: per-texel %d images %.3f s (%.0f images/s)\n", images, memPerTexel, images / memPerTexel);

  // ---- Written as PNG (what `nbtf decode` does)
  DecodeStackOptions o;
  o.format = ImageFormat::Png;
  o.progress = false;
  o.lights = lights;
  auto writePng = [&](const NbtfDecoder& d, const char* name) {
    fs::path dir = work / name;
    fs::remove_all(dir);
    DecodeStackResult r = writeDecodedStack(d, dir.string(), o);
    fs::remove_all(dir);
    return r.seconds;
  };
  double pngClustered = writePng(clustered, "png_clustered");
  std::printf("as PNG:    clustered %d images %.3f s (%.0f images/s)\n", images, pngClustered, images / pngClustered);
  double pngPerTexel = writePng(perTexel, "png_per_texel");
  std::printf("as PNG:    per-texel %d images %.3f s (%.0f images/s)\n", images, pngPerTexel, images / pngPerTexel);

  // ---- Batched queries
  const std::size_t n = quick ? 200000 : 2000000;
  std::vector<TexelQuery> queries = randomQueries(n, 7);
  std::vector<float> rgb(3 * n);
  double qClustered = bestOf(3, [&] { clustered.evaluate(queries.data(), n, rgb.data()); });
  double qPerTexel = bestOf(3, [&] { perTexel.evaluate(queries.data(), n, rgb.data()); });
  std::vector<UvQuery> uv(n);
  for (std::size_t i = 0; i < n; ++i) {
    auto l = queries[i].light.unitVector(), v = queries[i].view.unitVector();
    uv[i].u = (queries[i].x + 0.5f) / 100, uv[i].v = (queries[i].y + 0.5f) / 100;
    uv[i].light = {float(l[0]), float(l[1]), float(std::max(0.0, l[2]))};
    uv[i].view = {float(v[0]), float(v[1]), float(std::max(0.0, v[2]))};
  }
  double qUv = bestOf(3, [&] { clustered.evaluate(uv.data(), n, rgb.data()); });
  const double flops = clustered.flopsPerEvaluation();
  auto gflops = [&](double s) { return n / s * flops / 1e9; };
  std::printf("queries (texel + angles), clustered: %.3g queries/s = %.1f GFLOP/s\n", n / qClustered, gflops(qClustered));
  std::printf("queries (texel + angles), per-texel: %.3g queries/s = %.1f GFLOP/s\n", n / qPerTexel, gflops(qPerTexel));
  std::printf("queries (uv + unit vectors), clustered: %.3g queries/s = %.1f GFLOP/s\n", n / qUv, gflops(qUv));

  // ---- What the direction inputs cost: the same clustered shapes (random weights) with the
  // paper's 4 stereographic inputs and with the default's 20 (stereographic + 2 Fourier octaves), side by
  // side. Whole images compute the direction part of the first layer once per image; a query
  // brings its own directions, so it pays for the wider first layer and the sines and cosines.
  const NbtfDecoder inputKinds[2] = {NbtfDecoder(makeMaterial(true, 2, DirectionEncoding::Stereographic)),
                                     NbtfDecoder(makeMaterial(true, 2, DirectionEncoding::StereographicFourier2))};
  struct Seconds {
    double mem = 1e300, query = 1e300, uv = 1e300;
  } inputs[2];
  // Interleaved rounds, the best of each kept: the machine's speed drifts over seconds.
  for (int round = 0; round < 3; ++round)
    for (int kind = 0; kind < 2; ++kind) {
      const NbtfDecoder& d = inputKinds[kind];
      Seconds& t = inputs[kind];
      t.mem = std::min(t.mem, bestOf(1, [&] { decodeStack(d, SampleType::Srgb8, lights, {}, false); }));
      t.query = std::min(t.query, bestOf(1, [&] { d.evaluate(queries.data(), n, rgb.data()); }));
      t.uv = std::min(t.uv, bestOf(1, [&] { d.evaluate(uv.data(), n, rgb.data()); }));
    }
  for (int kind = 0; kind < 2; ++kind)
    std::printf("direction inputs %s (%.0f FLOPs): %d images in memory %.3f s; queries %.3g/s (texel + angles), "
                "%.3g/s (uv + unit vectors)\n",
                directionEncodingName(inputKinds[kind].directionEncoding()).c_str(),
                inputKinds[kind].flopsPerEvaluation(), images, inputs[kind].mem, n / inputs[kind].query,
                n / inputs[kind].uv);

  double eigen2 = eigenGemmGflops(2048, 3), torch2 = torchGemmGflops(2048, 3);
  std::printf("matmul 2048^2 float (again): Eigen %.1f GFLOP/s, libtorch mm %.1f GFLOP/s\n", eigen2, torch2);
  eigen = std::max(eigen, eigen2), torchRate = std::max(torchRate, torch2);

  std::printf("result images %d\n", images);
  std::printf("result mem_clustered_s %.4f\nresult mem_per_texel_s %.4f\n", memClustered, memPerTexel);
  std::printf("result png_clustered_s %.4f\nresult png_per_texel_s %.4f\n", pngClustered, pngPerTexel);
  std::printf("result query_clustered_qps %.6g\nresult query_per_texel_qps %.6g\nresult query_uv_qps %.6g\n",
              n / qClustered, n / qPerTexel, n / qUv);
  std::printf("result flops_per_eval %.0f\n", flops);
  std::printf("result eigen_gflops %.3f\nresult torch_gflops %.3f\n", eigen, torchRate);
  for (int kind = 0; kind < 2; ++kind) {
    const char* name = kind == 0 ? "stereographic" : "fourier";
    std::printf("result inputs_mem_%s_s %.4f\nresult inputs_query_%s_qps %.6g\nresult inputs_uv_%s_qps %.6g\n", name,
                inputs[kind].mem, name, n / inputs[kind].query, name, n / inputs[kind].uv);
  }
  std::printf("result isa %s\n", decoderIsaName(clustered.isa()).c_str());
  return 0;
}
