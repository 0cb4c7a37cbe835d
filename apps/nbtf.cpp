// nbtf: compress measured BTFs into a clustered neural representation and bring them back.
#include <cstring>
#include <iostream>

#include "commands.h"

namespace nbtf::cli {
namespace {
const Command kCommands[] = {
    {"info", infoMain, "Describe a BTF image stack or a .nbtf file"},
    {"compress", compressMain, "Compress a BTF image stack into a .nbtf file (clustered neural BTF)"},
    {"decode", decodeMain, "Reconstruct images from a .nbtf file (any angles, any size)"},
    {"query", queryMain, "Decoded RGB at texels and directions (single or CSV batch)"},
    {"eval", evalMain, "Compare a .nbtf file with its reference: RMSE report (md, html, json)"},
    {"cluster", clusterMain, "Cluster a BTF's ABRDFs (PCA + k-means++) and show the clusters"},
    {"render", renderMain, "Ray trace a material on an object; --compare a stack with its .nbtf"},
};

void printUsage() {
  std::cout << "usage: nbtf <command> [options]\n\ncommands:\n";
  for (const auto& c : kCommands) std::printf("  %-10s %s\n", c.name, c.summary);
  std::cout << "\n'nbtf <command> --help' shows a command's options.\n";
}
}  // namespace
}  // namespace nbtf::cli

int main(int argc, char** argv) {
  using namespace nbtf::cli;
  if (argc < 2 || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "help")) {
    printUsage();
    return argc < 2 ? 2 : 0;
  }
  for (const auto& c : kCommands)
    if (!std::strcmp(argv[1], c.name)) return c.run(argc - 1, argv + 1);
  std::cerr << "nbtf: unknown command '" << argv[1] << "'\n\n";
  printUsage();
  return 2;
}
