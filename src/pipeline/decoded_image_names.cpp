#include "pipeline/decoded_image_names.h"

#include <filesystem>

#include "io/btf_names.h"
#include "util/error.h"

namespace nbtf {
namespace fs = std::filesystem;

std::string decodedImagePath(Layout layout, ImageFormat format, const DirectionChoice& light,
                             const DirectionChoice& view, int numViews, int outputIndex) {
  std::string ext = extensionOf(format);
  const bool measured = light.measured() && view.measured();
  if (layout == Layout::Ubo2003 && !measured && outputIndex < 0)
    throw Error("decodedImagePath: an unmeasured direction in the UBO2003 layout needs the output index");
  std::string name =
      layout == Layout::Utia ? utiaFileName(light.direction, view.direction, ext)
      : outputIndex >= 0     ? ubo2003FileName(outputIndex, light.direction, view.direction, ext)
                             : ubo2003FileName(light.index * numViews + view.index, light.direction, view.direction, ext);
  return (fs::path(viewFolderName(view.direction)) / name).string();
}

}  // namespace nbtf
