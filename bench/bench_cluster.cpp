// nbtf-bench-cluster: the nbtf side of scripts/bench_cluster.sh.
//
//   nbtf-bench-cluster matrix --stack DIR -o data.f32        standardized ABRDFs of a BTF stack
//   nbtf-bench-cluster matrix --synthetic 100x100 -o data.f32 a built-in procedural weave
//   nbtf-bench-cluster run --matrix data.f32 --clusters 500,1000,2000 --components 32 --out DIR
//
// data.f32 is what both nbtf and scikit-learn read: "NBTFMAT1", uint64 rows, uint64 cols,
// then rows x cols float32, row-major (numpy's natural order). `run` writes DIR/nbtf.json
// (timings, inertia) and DIR/nbtf_labels_K.i32 (one int32 per texel) for each K.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cxxopts.hpp>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cluster/clustering.h"
#include "io/btf_loader.h"
#include "io/color.h"
#include "util/directions.h"
#include "preprocess/abrdf_matrix.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {
namespace {

constexpr char kMagic[8] = {'N', 'B', 'T', 'F', 'M', 'A', 'T', '1'};


// ---- The matrix file

void writeMatrix(const std::string& path, const MatrixXfCol& x) {
  writeAtomicVia(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    std::uint64_t rows = x.rows(), cols = x.cols();
    out.write(kMagic, 8);
    out.write(reinterpret_cast<const char*>(&rows), 8);
    out.write(reinterpret_cast<const char*>(&cols), 8);
    const Eigen::Index block = 256;
    std::vector<float> buffer(block * cols);
    for (Eigen::Index r0 = 0; r0 < x.rows(); r0 += block) {
      Eigen::Index n = std::min(block, x.rows() - r0);
      Eigen::Map<Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(buffer.data(), n, cols) =
          x.middleRows(r0, n);
      out.write(reinterpret_cast<const char*>(buffer.data()), n * cols * sizeof(float));
    }
    if (!out) throw fileError(tmp, "write failed");
  });
}

MatrixXfCol readMatrix(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fileError(path, "cannot open");
  char magic[8];
  std::uint64_t rows = 0, cols = 0;
  in.read(magic, 8);
  in.read(reinterpret_cast<char*>(&rows), 8);
  in.read(reinterpret_cast<char*>(&cols), 8);
  if (!in || std::memcmp(magic, kMagic, 8) != 0) throw fileError(path, "not an NBTFMAT1 matrix file");
  MatrixXfCol x(rows, cols);
  const Eigen::Index block = 256;
  std::vector<float> buffer(block * cols);
  for (Eigen::Index r0 = 0; r0 < static_cast<Eigen::Index>(rows); r0 += block) {
    Eigen::Index n = std::min<Eigen::Index>(block, rows - r0);
    in.read(reinterpret_cast<char*>(buffer.data()), n * cols * sizeof(float));
    if (!in) throw fileError(path, "truncated matrix data");
    x.middleRows(r0, n) =
        Eigen::Map<Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(buffer.data(), n, cols);
  }
  return x;
}

// ---- A procedural material, when no synthetic stack is at hand
//
// A plain weave of two yarn colours: each texel lies on a warp or weft thread whose
// cylindrical profile tilts the normal across the thread; Lambert plus a Blinn-Phong sheen
// with per-thread roughness and colour jitter, per-texel fibre normals and per-sample camera
// noise, quantized to 8-bit sRGB like a UBO2003 JPEG.
// Enough structure for PCA and k-means to behave as on a real fabric (a decaying spectrum,
// clusters of unequal sizes), which random low-rank data does not give.

float hash01(std::uint32_t a) {
  a ^= a >> 16, a *= 0x7feb352dU, a ^= a >> 15, a *= 0x846ca68bU, a ^= a >> 16;
  return (a & 0xffffff) / 16777216.0f;
}

MatrixXfCol proceduralWeave(int width, int height) {
  const auto& dirs = hemisphere81();
  const int images = static_cast<int>(dirs.size() * dirs.size());
  const Eigen::Index texels = static_cast<Eigen::Index>(width) * height;
  MatrixXfCol x(texels, 3 * static_cast<Eigen::Index>(images));
  struct Texel {
    float n[3], albedo[3], shininess, specular;
  };
  std::vector<Texel> texel(texels);
  const int period = 10;  // texels per thread
  for (int y = 0; y < height; ++y)
    for (int xx = 0; xx < width; ++xx) {
      int tx = xx / period, ty = y / period;
      bool warp = ((tx + ty) % 2) == 0;  // which thread is on top
      float u = (warp ? (xx % period) : (y % period)) / float(period - 1) * 2 - 1;  // across the thread
      std::uint32_t thread = warp ? 1000u + tx : 2000u + ty;
      float tilt = 0.9f * u;  // cylinder profile, plus fibre-level jitter per texel
      std::uint32_t texelHash = static_cast<std::uint32_t>(y * width + xx) * 2654435761u;
      float jx = 0.3f * (hash01(texelHash) - 0.5f), jy = 0.3f * (hash01(texelHash ^ 0x5bd1e995u) - 0.5f);
      float nx = (warp ? tilt : 0) + jx, ny = (warp ? 0 : tilt) + jy, nz = 1;
      float len = std::sqrt(nx * nx + ny * ny + nz * nz);
      Texel& t = texel[static_cast<std::size_t>(y) * width + xx];
      t.n[0] = nx / len, t.n[1] = ny / len, t.n[2] = nz / len;
      const float warpColour[3] = {0.55f, 0.12f, 0.10f}, weftColour[3] = {0.15f, 0.22f, 0.45f};
      float jitter = 0.8f + 0.4f * hash01(thread), fibre = 0.9f + 0.2f * hash01(thread * 7919u + xx * 31u + y);
      for (int c = 0; c < 3; ++c) t.albedo[c] = (warp ? warpColour[c] : weftColour[c]) * jitter * fibre;
      t.shininess = 8 + 40 * hash01(thread + 17);
      t.specular = 0.05f + 0.1f * hash01(thread + 29);
    }
  Progress bar("procedural weave", images, true);
  parallelForDynamic(images, [&](std::size_t image, int) {
    auto l = dirs[image / dirs.size()].unitVector();
    auto v = dirs[image % dirs.size()].unitVector();
    float h[3] = {float(l[0] + v[0]), float(l[1] + v[1]), float(l[2] + v[2])};
    float hl = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    for (float& c : h) c /= hl;
    for (Eigen::Index t = 0; t < texels; ++t) {
      const Texel& p = texel[t];
      float nl = std::max(0.0f, float(p.n[0] * l[0] + p.n[1] * l[1] + p.n[2] * l[2]));
      float nv = std::max(0.0f, float(p.n[0] * v[0] + p.n[1] * v[1] + p.n[2] * v[2]));
      float nh = std::max(0.0f, p.n[0] * h[0] + p.n[1] * h[1] + p.n[2] * h[2]);
      float masking = nv > 0 ? 1.0f : 0.3f;  // neighbouring threads still scatter some light
      float spec = p.specular * std::pow(nh, p.shininess) * nl;
      // Camera noise: about 3% multiplicative, per sample.
      std::uint32_t sampleHash = static_cast<std::uint32_t>(t) * 2246822519u + static_cast<std::uint32_t>(image) * 3266489917u;
      for (int c = 0; c < 3; ++c) {
        float noise = 1.0f + 0.06f * (hash01(sampleHash + 374761393u * c) - 0.5f);
        float linear = noise * (masking * (p.albedo[c] * nl + spec) + 0.01f * p.albedo[c]);
        x(t, 3 * static_cast<Eigen::Index>(image) + c) = srgb8ToLinear(linearToSrgb8(linear));
      }
    }
    bar.advance();
  });
  bar.finish();
  return x;
}

// ---- Subcommands

int matrixMain(int argc, char** argv) {
  cxxopts::Options options("nbtf-bench-cluster matrix", "Write the standardized ABRDF matrix the benchmark reads");
  options.add_options()("stack", "BTF stack folder", cxxopts::value<std::string>())(
      "synthetic", "Procedural weave WxH instead of a stack", cxxopts::value<std::string>())(
      "o,output", "Matrix file", cxxopts::value<std::string>());
  auto args = options.parse(argc, argv);
  if (!args.count("output")) throw Error("matrix: -o is required");
  MatrixXfCol x;
  if (args.count("stack")) {
    BtfStack stack = loadBtfStack(args["stack"].as<std::string>());
    x = abrdfMatrix(stack);
  } else if (args.count("synthetic")) {
    int w = 0, h = 0;
    char sep = 0;
    std::istringstream in(args["synthetic"].as<std::string>());
    if (!(in >> w >> sep >> h) || sep != 'x' || w < 1 || h < 1) throw Error("matrix: --synthetic expects WxH");
    x = proceduralWeave(w, h);
  } else {
    throw Error("matrix: give --stack DIR or --synthetic WxH");
  }
  standardizeInPlace(x);
  writeMatrix(args["output"].as<std::string>(), x);
  std::printf("wrote %s: %ld texels x %ld dimensions (log + standardized)\n", args["output"].as<std::string>().c_str(),
              static_cast<long>(x.rows()), static_cast<long>(x.cols()));
  return 0;
}

int runMain(int argc, char** argv) {
  cxxopts::Options options("nbtf-bench-cluster run", "Time PCA and k-means on a matrix file");
  options.add_options()("matrix", "Matrix file", cxxopts::value<std::string>())(
      "clusters", "k values", cxxopts::value<std::vector<int>>()->default_value("500,1000,2000"))(
      "components", "PCA components", cxxopts::value<int>()->default_value("32"))(
      "power-iterations", "PCA power iterations (-1: nbtf's default)", cxxopts::value<int>()->default_value("-1"))(
      "oversampling", "PCA oversampling (-1: nbtf's default)", cxxopts::value<int>()->default_value("-1"))(
      "seed", "Seed", cxxopts::value<std::uint64_t>()->default_value("1"))(
      "threads", "Worker threads (0 = all cores)", cxxopts::value<int>()->default_value("0"))(
      "repeat", "Runs per stage; the fastest is reported", cxxopts::value<int>()->default_value("1"))(
      "out", "Output folder", cxxopts::value<std::string>());
  auto args = options.parse(argc, argv);
  if (!args.count("matrix") || !args.count("out")) throw Error("run: --matrix and --out are required");
  setThreadCount(args["threads"].as<int>());
  const std::string out = args["out"].as<std::string>();
  Progress::setQuiet(true);
  MatrixXfCol x = readMatrix(args["matrix"].as<std::string>());

  nlohmann::json report;
  report["texels"] = x.rows();
  report["dimensions"] = x.cols();
  report["threads"] = threadCount();
  PcaOptions pcaOptions;
  pcaOptions.components = args["components"].as<int>();
  pcaOptions.seed = args["seed"].as<std::uint64_t>();
  if (args["power-iterations"].as<int>() >= 0) pcaOptions.powerIterations = args["power-iterations"].as<int>();
  if (args["oversampling"].as<int>() >= 0) pcaOptions.oversampling = args["oversampling"].as<int>();
  pcaOptions.progress = false;
  // A shared machine's load comes and goes: time every stage `repeat` times, keep the fastest
  // (the scikit-learn side does the same). Results are deterministic, so any run's are the same.
  const int repeat = std::max(1, args["repeat"].as<int>());
  PcaResult pca;
  double pcaSeconds = 1e300;
  for (int r = 0; r < repeat; ++r) {
    auto start = std::chrono::steady_clock::now();
    pca = randomizedPca(x, pcaOptions);
    pcaSeconds = std::min(pcaSeconds, secondsSince(start));
  }
  report["repeat"] = repeat;
  report["pca"] = {{"seconds", pcaSeconds},
                   {"components", pcaOptions.components},
                   {"power_iterations", pcaOptions.powerIterations},
                   {"oversampling", pcaOptions.oversampling},
                   {"explained_variance_ratio", pca.explainedRatio()}};
  for (int k : args["clusters"].as<std::vector<int>>()) {
    KMeansOptions kmeansOptions;
    kmeansOptions.clusters = k;
    kmeansOptions.seed = args["seed"].as<std::uint64_t>();
    kmeansOptions.progress = false;
    KMeansResult km;
    double seconds = 1e300;
    for (int r = 0; r < repeat; ++r) {
      auto start = std::chrono::steady_clock::now();
      KMeansResult run = kmeansPlusPlus(pca.scores, kmeansOptions);
      double s = secondsSince(start);
      if (s < seconds) seconds = s, km = std::move(run);
    }
    report["kmeans"].push_back({{"k", k},
                                {"seconds", seconds},
                                {"seeding_seconds", km.seedingSeconds},
                                {"lloyd_seconds", km.lloydSeconds},
                                {"iterations", km.iterations},
                                {"converged", km.converged},
                                {"inertia", km.inertia}});
    std::string labels = out + "/nbtf_labels_" + std::to_string(k) + ".i32";
    writeFileAtomic(labels, km.ids.data(), km.ids.size() * sizeof(std::int32_t));
    std::fprintf(stderr, "nbtf k=%d: %.3f s (seeding %.3f, lloyd %.3f, %d iterations), inertia %.6g\n", k, seconds,
                 km.seedingSeconds, km.lloydSeconds, km.iterations, km.inertia);
  }
  writeFileAtomic(out + "/nbtf.json", report.dump(2));
  std::fprintf(stderr, "nbtf pca: %.3f s, explained %.4f\n", report["pca"]["seconds"].get<double>(),
               pca.explainedRatio());
  return 0;
}

}  // namespace
}  // namespace nbtf

int main(int argc, char** argv) {
  using namespace nbtf;
  try {
    if (argc >= 2 && !std::strcmp(argv[1], "matrix")) return matrixMain(argc - 1, argv + 1);
    if (argc >= 2 && !std::strcmp(argv[1], "run")) return runMain(argc - 1, argv + 1);
    std::cerr << "usage: nbtf-bench-cluster matrix|run [options]\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "nbtf-bench-cluster: error: " << userMessage(e) << std::endl;
    return 1;
  }
}
