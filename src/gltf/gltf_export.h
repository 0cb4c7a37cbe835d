// `nbtf export-gltf`'s work: a BTF (an image stack, a UBO2014 file or a .nbtf) in, a fitted
// glTF 2.0 material out (gltf_fit.h), measured against everything there is to measure it
// against (gltf_report.h) and written as a folder (gltf_write.h).
#pragma once
#include <string>
#include <vector>

#include "gltf/gltf_fit.h"
#include "gltf/gltf_report.h"
#include "gltf/gltf_write.h"
#include "util/layout.h"

namespace nbtf::gltf {

// An extension of the material (KHR_materials_specular, KHR_materials_sheen): fitted and kept
// where it lowers the error over all images of the input by at least kExtensionMinGain (auto:
// another texture for less is not worth its bytes), always written (on), or not fitted (off).
// Auto tries specular first, then sheen on top of what was kept.
constexpr double kExtensionMinGain = 0.01;
enum class ExtensionMode { Auto, On, Off };
// "auto" | "on" | "off"; throws naming `option` (--sheen, --specular).
ExtensionMode parseExtensionMode(const std::string& text, const std::string& option);
std::string extensionModeName(ExtensionMode mode);

struct ExtensionTrial {  // auto: the input's RMSE without and with the extension
  std::string name;
  double without = 0, with = 0;
  bool kept = false;
};

struct ExportOptions {
  FitOptions fit;
  ExtensionMode sheen = ExtensionMode::Auto, specular = ExtensionMode::Auto;
  Crop crop;              // of an image stack input (or of the reference)
  std::string reference;  // with a .nbtf input: the stack it was made from, to measure against (optional)
  bool progress = true;
};

struct ExportSummary {
  std::string input, output;
  int width = 0, height = 0, images = 0;
  double exposure = 0, alpha = 0;
  FitSummary fit;
  bool sheen = false, specular = false;  // those textures were written
  std::vector<ExtensionTrial> trials;    // auto's decisions
  double measureSeconds = 0;
  std::vector<FitError> errors;  // stack, ground truth, nbtf: those that exist
  TextureBytes bytes;
  double ratio = 0;  // raw float32 / texture bytes
};

// Throws nbtf::Error naming the input, the output or the option before any long work when
// something cannot be done (an output that is not ours, a .nbtf without a matching reference).
ExportSummary exportGltf(const std::string& input, const std::string& outputDir, const ExportOptions& options);

// The report fit_report.json holds (texture bytes are added by the writer).
std::string fitReportJson(const ExportSummary& s, const ExportOptions& options);
// The command's closing lines.
std::string formatExportSummary(const ExportSummary& s);

}  // namespace nbtf::gltf
