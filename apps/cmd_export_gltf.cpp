// nbtf export-gltf <stack | file.btf | file.nbtf> -o DIR: the glTF 2.0 metallic-roughness
// material fitted per texel to the BTF (base colour, metallic-roughness and normal textures,
// the material on a plane and a sphere, a report of the fit's error): src/gltf/, docs/gltf.md.
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "gltf/gltf_export.h"

namespace nbtf::cli {

int exportGltfMain(int argc, char** argv) {
  return runGuarded("export-gltf", [&] {
    cxxopts::Options options("nbtf export-gltf",
                             "A glTF 2.0 material (metallic-roughness + normal map) fitted per texel to a BTF, "
                             "for Blender, three.js, Godot and every glTF renderer");
    options.positional_help("<image stack | file.btf | file.nbtf> -o DIR");
    options.add_options()("input", "The BTF: an image stack folder, a UBO2014 .btf file or a .nbtf file",
                          cxxopts::value<std::string>())(
        "o,output", "Output folder: material.gltf, meshes.bin, base_color.png, metallic_roughness.png, normal.png, "
                    "fit_report.json",
        cxxopts::value<std::string>())(
        "reference", "With a .nbtf input: the stack it was made from, to measure the fit against as well",
        cxxopts::value<std::string>())(
        "samples", "(light, view) images the fit uses per texel (all when there are fewer)",
        cxxopts::value<int>()->default_value("512"))(
        "iterations", "Most Levenberg-Marquardt steps per texel (a converged texel stops)", cxxopts::value<int>()->default_value("50"))(
        "max-tilt", "Largest angle of a texel's shading normal from the surface normal (degrees)",
        cxxopts::value<double>()->default_value("60"))(
        "min-roughness", "Smallest roughness the fit may choose (a narrower lobe than the measured directions resolve "
                         "is not identifiable)", cxxopts::value<double>()->default_value("0.1"))(
        "sheen", "KHR_materials_sheen (fibres' grazing sheen): auto (kept where it lowers the error), on, off",
        cxxopts::value<std::string>()->default_value("auto"))(
        "specular", "KHR_materials_specular (the dielectric's F0 per texel): auto, on, off",
        cxxopts::value<std::string>()->default_value("auto"))(
        "seed", "Random seed (which images the fit samples)", cxxopts::value<long long>()->default_value("1"));
    addCropOption(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "input", argc, argv, args)) return 0;
    if (!args.count("input")) throw Error("missing <input> (see 'nbtf export-gltf --help')");
    if (!args.count("output")) throw Error("missing -o DIR (the folder to write the glTF material into)");
    const std::string input = args["input"].as<std::string>(), dir = args["output"].as<std::string>();
    gltf::ExportOptions o;
    if (args.count("reference")) o.reference = args["reference"].as<std::string>();
    std::vector<PathUse> inputs = {{"<input>", input}};
    if (!o.reference.empty()) inputs.push_back({"--reference", o.reference});
    refuseOverlappingPaths(inputs, {{"-o", dir, true}});
    checkFolderCreatable(dir);
    o.fit.samples = args["samples"].as<int>();
    o.fit.iterations = args["iterations"].as<int>();
    o.fit.maxTiltDeg = args["max-tilt"].as<double>();
    o.fit.minRoughness = args["min-roughness"].as<double>();
    o.sheen = gltf::parseExtensionMode(args["sheen"].as<std::string>(), "--sheen");
    o.specular = gltf::parseExtensionMode(args["specular"].as<std::string>(), "--specular");
    const long long seed = args["seed"].as<long long>();
    if (seed < 0) throw Error("--seed must be >= 0, got " + std::to_string(seed));
    o.fit.seed = static_cast<std::uint64_t>(seed);
    if (auto crop = cropOption(args)) o.crop = *crop;
    o.progress = !quiet(args);
    const gltf::ExportSummary s = gltf::exportGltf(input, dir, o);
    std::cout << gltf::formatExportSummary(s);
    return 0;
  });
}

}  // namespace nbtf::cli
