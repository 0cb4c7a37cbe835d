#include "synth/synth_ubo2014.h"

#include <chrono>
#include <filesystem>
#include <memory>
#include <sstream>

#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf::synth {

SynthUbo2014Summary writeSynthUbo2014(const SynthOptions& options, const std::string& path,
                                      const Ubo2014FactorizeOptions& factorize) {
  const auto start = std::chrono::steady_clock::now();
  SynthOptions checked = options;
  checked.layout = Layout::Ubo2003, checked.format = ImageFormat::Jpg;  // the image layout does not apply
  validateSynthOptions(checked);
  checkUbo2014FactorizeOptions(factorize);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw fileError(path, "is a folder; the ubo2014 layout writes one .btf file (e.g. -o fabric.btf)");

  SynthMaterial material(options.preset, options.width, options.height, options.seed, options.render);
  const std::vector<Direction>& dirs = dome151();
  const int n = static_cast<int>(dirs.size());
  std::vector<std::shared_ptr<const SynthMaterial::LightPass>> lights(n);
  std::vector<std::shared_ptr<const SynthMaterial::ViewPass>> views(n);
  {
    Progress progress("shadows", 2 * n, options.progress);
    parallelForDynamic(2 * n, [&](std::size_t i, int) {
      if (static_cast<int>(i) < n) lights[i] = material.prepareLight(dirs[i]);
      else views[i - n] = material.prepareView(dirs[i - n]);
      progress.advance();
    });
  }

  Ubo2014FactorizeOptions f = factorize;
  f.progress = options.progress;
  std::ostringstream xml;
  xml << "<nbtf-synth preset=\"" << options.preset << "\" seed=\"" << options.seed << "\" width=\"" << options.width
      << "\" height=\"" << options.height << "\" parallax=\"" << (options.render.parallax ? 1 : 0)
      << "\" supersampling=\"" << options.render.supersampling << "\" components=\"" << f.components
      << "\" color_model=\"" << f.colorModel << "\"/>";
  f.xml = xml.str();

  SynthUbo2014Summary summary;
  Ubo2014Btf btf = factorizeUbo2014(
      dirs, dirs, options.width, options.height,
      [&](int image, float* rgb) { material.render(*lights[image / n], *views[image % n], rgb); }, f,
      &summary.factorization);
  lights.clear(), views.clear();
  btf.write(path);
  summary.images = n * n;
  summary.fileBytes = std::filesystem::file_size(path, ec);
  summary.seconds = secondsSince(start);
  return summary;
}

}  // namespace nbtf::synth
