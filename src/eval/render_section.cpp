#include "eval/render_section.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "util/error.h"

namespace nbtf {

RenderSection loadRenderSection(const std::string& folder) {
  namespace fs = std::filesystem;
  const std::string jsonPath = (fs::path(folder) / "compare.json").string();
  std::ifstream in(jsonPath);
  if (!in) throw fileError(jsonPath, "cannot open (expected the folder `nbtf render --compare` writes)");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
    RenderSection s;
    s.folder = folder;
    s.scene = j.at("scene").get<std::string>();
    s.sampling = j.at("sampling").get<std::string>();
    s.reference = j.at("reference").get<std::string>();
    s.compressed = j.at("compressed").get<std::string>();
    s.space = j.at("space").get<std::string>();
    s.width = j.at("width").get<int>();
    s.height = j.at("height").get<int>();
    s.errorMagnification = j.at("error_magnification").get<double>();
    s.rmseAll = j.at("rmse").at("all").at("rmse").get<double>();
    s.rmseDark = j.at("rmse").at("dark10").at("rmse").get<double>();
    s.rmseBright = j.at("rmse").at("bright10").at("rmse").get<double>();
    s.referenceImage = readImage8((fs::path(folder) / "reference.png").string());
    s.compressedImage = readImage8((fs::path(folder) / "compressed.png").string());
    s.errorImage = readImage8((fs::path(folder) / "error.png").string());
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw fileError(jsonPath, std::string("not a render comparison: ") + e.what());
  }
}

}  // namespace nbtf
