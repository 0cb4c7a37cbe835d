// nbtf: compress measured BTFs into a clustered neural representation and bring them back.
#include <cstring>
#include <iostream>

#include "commands.h"
#include "util/memory.h"

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
    {"export-shader", exportShaderMain, "The decoder as a GLSL ES 3.00 function, its data as textures"},
    {"export-gltf", exportGltfMain, "A glTF 2.0 material fitted to a BTF, for Blender and any glTF renderer"},
    {"view", viewMain, "A self-contained WebGL2 page showing the material live"},
};

void printUsage() {
  std::cout << "usage: nbtf <command> [options]\n       nbtf help <command>\n       nbtf --version\n\ncommands:\n";
  for (const auto& c : kCommands) std::printf("  %-13s %s\n", c.name, c.summary);
  std::cout << "\n'nbtf <command> --help' (or 'nbtf help <command>') shows a command's options.\n";
}

const Command* findCommand(const char* name) {
  for (const auto& c : kCommands)
    if (!std::strcmp(name, c.name)) return &c;
  return nullptr;
}

int unknownCommand(const char* name) {
  std::cerr << "nbtf: unknown command '" << name << "'\n\n";
  printUsage();
  return 2;
}
}  // namespace
}  // namespace nbtf::cli

int main(int argc, char** argv) {
  using namespace nbtf::cli;
  nbtf::reuseFreedMemory();
  if (argc >= 2 && (!std::strcmp(argv[1], "--version") || !std::strcmp(argv[1], "version"))) {
    std::printf("nbtf %s\n", NBTF_VERSION);
    return 0;
  }
  if (argc >= 3 && !std::strcmp(argv[1], "help")) {  // nbtf help <command> = nbtf <command> --help
    const Command* c = findCommand(argv[2]);
    if (!c) return unknownCommand(argv[2]);
    char help[] = "--help";
    char* args[] = {argv[2], help, nullptr};
    return c->run(2, args);
  }
  if (argc < 2 || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "help")) {
    printUsage();
    return argc < 2 ? 2 : 0;
  }
  if (const Command* c = findCommand(argv[1])) return c->run(argc - 1, argv + 1);
  return unknownCommand(argv[1]);
}
