// The `nbtf` subcommands. Each lives in its own cmd_*.cpp, parses its own options with
// cxxopts and calls into the library; main() only dispatches through kCommands.
#pragma once
#include <string>

namespace nbtf::cli {

using CommandMain = int (*)(int argc, char** argv);

struct Command {
  const char* name;
  CommandMain run;
  const char* summary;
};

int infoMain(int argc, char** argv);
int decodeMain(int argc, char** argv);
int queryMain(int argc, char** argv);
int evalMain(int argc, char** argv);
int clusterMain(int argc, char** argv);
int compressMain(int argc, char** argv);
int renderMain(int argc, char** argv);
int exportShaderMain(int argc, char** argv);
int exportGltfMain(int argc, char** argv);
int viewMain(int argc, char** argv);

}  // namespace nbtf::cli
