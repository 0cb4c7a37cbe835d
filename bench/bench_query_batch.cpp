// The C++ side of scripts/bench_python.sh: batched queries (texel + angles) through
// NbtfDecoder::evaluate, the path the Python module's Material.query calls, at several batch
// sizes. Usage: bench_query_batch FILE.nbtf SECONDS N1 [N2 ...]; per batch size prints
//   result N seconds_per_call
// (the median of 5 rounds, each repeating the call for at least SECONDS / 5).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "codec/decoder.h"
#include "util/error.h"

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bench_query_batch FILE.nbtf SECONDS N1 [N2 ...]\n");
    return 2;
  }
  try {
    const nbtf::NbtfDecoder decoder = nbtf::NbtfDecoder::open(argv[1]);
    const double seconds = std::atof(argv[2]);
    std::mt19937 rng(1);
    for (int a = 3; a < argc; ++a) {
      const std::size_t n = std::strtoull(argv[a], nullptr, 10);
      std::vector<nbtf::TexelQuery> queries(n);
      std::uniform_int_distribution<int> x(0, decoder.width() - 1), y(0, decoder.height() - 1);
      std::uniform_real_distribution<double> theta(0, 90), phi(0, 360);
      for (auto& q : queries) q = {x(rng), y(rng), {theta(rng), phi(rng)}, {theta(rng), phi(rng)}};
      std::vector<float> rgb(3 * n);
      std::vector<double> rounds;
      for (int round = 0; round < 5; ++round) {
        long calls = 0;
        const auto start = std::chrono::steady_clock::now();
        double elapsed = 0;
        do {
          decoder.evaluate(queries.data(), n, rgb.data());
          ++calls;
          elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        } while (elapsed < seconds / 5);
        rounds.push_back(elapsed / calls);
      }
      std::sort(rounds.begin(), rounds.end());
      std::printf("result %zu %.6g\n", n, rounds[2]);
      std::fflush(stdout);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_query_batch: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
