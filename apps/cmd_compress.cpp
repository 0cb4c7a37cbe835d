// nbtf compress <input> -o <out.nbtf>: the whole pipeline (load, preprocess, PCA,
// k-means++, train, write) with a summary table at the end; --method pca: the classic PCA
// baseline instead (load, PCA, write).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>

#include "cli_common.h"
#include "commands.h"
#include "interrupt.h"
#include "options/compress_options.h"
#include "util/atomic_file.h"
#include "util/progress.h"

namespace nbtf::cli {
int compressMain(int argc, char** argv) {
  return runGuarded("compress", [&] {
    cxxopts::Options options("nbtf compress", "Compress a BTF image stack into a .nbtf file");
    options.positional_help("<input> -o <out.nbtf>");
    addCompressOptions(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "input", argc, argv, args)) return 0;
    CompressRequest request = compressRequest(args, options.program());
    prepareCompressOutputs(request);
    const std::string& output = request.output;
    const std::string& statsPath = request.statsPath;
    CompressOptions& o = request.options;
    const DistributedConfig& dist = o.train.distributed;
    if (o.train.resume) {
      std::error_code ec;
      if (std::filesystem::exists(o.train.checkpointPath, ec))
        std::fprintf(stderr, "nbtf compress: resuming from %s\n", o.train.checkpointPath.c_str());
      else
        std::fprintf(stderr, "nbtf compress: --resume: no checkpoint at %s, starting from the beginning\n",
                     o.train.checkpointPath.c_str());
    }
    o.stopFlag = stopOnInterrupt(
        "\nnbtf compress: interrupt received, stopping after a checkpoint (Ctrl-C again to abort)\n");

    CompressStats stats = compressBtf(request.input, output, o);
    if (stats.interrupted) {
      std::error_code ec;
      if (dist.enabled()) {  // --resume is for one process; rank 0's checkpoint can go on in one
        const bool checkpoint = dist.rank == 0 && !stats.checkpointPath.empty() &&
                                std::filesystem::exists(stats.checkpointPath, ec);
        std::fprintf(stderr,
                     "nbtf compress: interrupted; nothing written to %s. A data-parallel run cannot --resume: "
                     "restart every rank with the same command to train from the beginning%s\n",
                     output.c_str(),
                     checkpoint ? (", or continue in one process from the training state in " + stats.checkpointPath +
                                   ": the same command without --world-size, --rank and --master, with --resume.")
                                      .c_str()
                                : ".");
      } else if (!stats.checkpointPath.empty() && std::filesystem::exists(stats.checkpointPath, ec))
        std::fprintf(stderr,
                     "nbtf compress: interrupted; nothing written to %s. Training state is in %s: run the same "
                     "command with --resume to continue.\n",
                     output.c_str(), stats.checkpointPath.c_str());
      else
        std::fprintf(stderr, "nbtf compress: interrupted before training started; nothing written to %s.\n",
                     output.c_str());
      if (!statsPath.empty()) writeFileAtomic(statsPath, compressStatsJson(stats));
      return 130;
    }
    if (stats.worker) {
      std::printf("\nrank %d of %d: trained its share of %lld steps (%.2f ms all-reduce per step); rank 0 writes %s\n",
                  dist.rank, dist.worldSize, static_cast<long long>(stats.steps), 1e3 * stats.allReduceSecondsPerStep,
                  output.c_str());
      return 0;
    }
    std::printf("\n%s", formatCompressSummary(stats).c_str());
    if (!statsPath.empty()) writeFileAtomic(statsPath, compressStatsJson(stats));
    return 0;
  });
}

}  // namespace nbtf::cli
