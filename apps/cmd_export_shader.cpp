// nbtf export-shader <file.nbtf> -o DIR: the file's decoder as a GLSL ES 3.00 function, its data
// as RGBA32F textures and a JSON manifest (src/shader/shader_export.h, docs/shader.md).
#include <cstdio>

#include "cli_common.h"
#include "codec/nbtf_file.h"
#include "commands.h"
#include "shader/shader_export.h"

namespace nbtf::cli {

int exportShaderMain(int argc, char** argv) {
  return runGuarded("export-shader", [&] {
    cxxopts::Options options("nbtf export-shader",
                             "The decoder of a .nbtf file as a GLSL ES 3.00 function, with its data as textures");
    options.positional_help("<file.nbtf> -o DIR");
    options.add_options()("file", "Compressed material (.nbtf)", cxxopts::value<std::string>())(
        "o,output", "Output folder: nbtf_decoder.glsl, manifest.json, one .f32 file per texture",
        cxxopts::value<std::string>())(
        "weights", "Where the decoder's weights live: auto (uniform blocks when they fit 12 of 16 KiB), texture, "
                   "uniform-blocks", cxxopts::value<std::string>()->default_value("auto"));
    cxxopts::ParseResult args;
    if (!parseCommand(options, "file", argc, argv, args)) return 0;
    if (!args.count("file")) throw Error("missing <file.nbtf> (see 'nbtf export-shader --help')");
    if (!args.count("output")) throw Error("missing -o DIR (the folder to write the shader into)");
    const std::string path = args["file"].as<std::string>(), dir = args["output"].as<std::string>();
    refuseOverlappingPaths({{"<file.nbtf>", path}}, {{"-o", dir, true}});
    checkFolderCreatable(dir);
    const ShaderDecoder shader =
        buildShaderDecoder(readNbtf(path), path, parseShaderWeights(args["weights"].as<std::string>()));
    writeShaderExport(shader, dir);
    if (!quiet(args)) {
      std::size_t bytes = 0;
      for (const ShaderTexture& t : shader.textures) bytes += t.data.size() * sizeof(float);
      for (const ShaderUniformBlock& b : shader.uniformBlocks) bytes += b.data.size() * sizeof(float);
      std::printf("wrote %s: nbtf_decoder.glsl, manifest.json, %zu textures and %zu uniform blocks (%.1f KiB)\n",
                  dir.c_str(), shader.textures.size(), shader.uniformBlocks.size(), bytes / 1024.0);
      std::printf("per pixel: %.0f operations (%.0f multiply-adds), %.0f uniform loads, %.0f texture fetches\n",
                  shader.cost.operations(), shader.cost.multiplyAdds, shader.cost.uniformLoads,
                  shader.cost.textureFetches);
    }
    return 0;
  });
}

}  // namespace nbtf::cli
