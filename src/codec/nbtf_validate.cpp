// CompressedBtf::validate: every invariant of a material that the writer and the reader check:
// here the ones every material shares, then its model kind's (codec/methods/).
#include <algorithm>
#include <climits>
#include <cmath>
#include <nlohmann/json.hpp>

#include "codec/methods/method.h"
#include "codec/nbtf_format.h"
#include "util/error.h"

namespace nbtf {
namespace {

using format::kMaxJsonDepth;
using format::kMaxSide;

// Nesting depth of a JSON text (brackets outside strings); bounds the parser's work on
// hostile metadata before nlohmann sees it.
int jsonDepth(const std::string& text) {
  int depth = 0, maxDepth = 0;
  bool inString = false, escape = false;
  for (char c : text) {
    if (inString) {
      if (escape) escape = false;
      else if (c == '\\') escape = true;
      else if (c == '"') inString = false;
    } else if (c == '"') {
      inString = true;
    } else if (c == '{' || c == '[') {
      maxDepth = std::max(maxDepth, ++depth);
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return maxDepth;
}

void checkMetadata(const std::string& json, const std::string& name) {
  if (jsonDepth(json) > kMaxJsonDepth)
    throw fileError(name, "metadata JSON is nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  auto first = json.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || json[first] != '{' || !nlohmann::json::accept(json))
    throw fileError(name, "metadata is not a valid JSON object");
}

}  // namespace

void CompressedBtf::validate(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  const MethodKind& kind = methodKind(method, name);
  if (!isDirectionEncoding(static_cast<int>(directionEncoding)))
    throw fail("unknown direction encoding code " + std::to_string(static_cast<int>(directionEncoding)));
  if (valueSpace != ValueSpace::LinearOverAlpha)
    throw fail("unknown value space code " + std::to_string(static_cast<int>(valueSpace)));

  // Geometry
  if (width < 1 || height < 1 || width > int(kMaxSide) || height > int(kMaxSide))
    throw fail("texel size " + std::to_string(width) + " x " + std::to_string(height) + " is out of range");
  if (static_cast<std::int64_t>(width) * height > INT_MAX) throw fail("too many texels");
  if (sourceWidth < 1 || sourceHeight < 1 || sourceWidth > int(kMaxSide) || sourceHeight > int(kMaxSide))
    throw fail("source image size " + std::to_string(sourceWidth) + " x " + std::to_string(sourceHeight) +
               " is out of range");
  if (crop.empty()) {
    if (width != sourceWidth || height != sourceHeight)
      throw fail("texel size differs from the source image size but no crop is recorded");
  } else {
    if (crop.x < 0 || crop.y < 0 || crop.width < 1 || crop.height < 1 ||
        static_cast<std::int64_t>(crop.x) + crop.width > sourceWidth ||
        static_cast<std::int64_t>(crop.y) + crop.height > sourceHeight)
      throw fail("crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," + std::to_string(crop.width) +
                 "," + std::to_string(crop.height) + " lies outside the " + std::to_string(sourceWidth) + " x " +
                 std::to_string(sourceHeight) + " source images");
    if (crop.width != width || crop.height != height) throw fail("crop size differs from the texel size");
  }
  if (lights.empty() || views.empty()) throw fail("no light or view directions");
  if (static_cast<std::int64_t>(lights.size()) * static_cast<std::int64_t>(views.size()) > INT_MAX)
    throw fail("too many images");
  for (std::size_t i = 0; i < lights.size(); ++i) {
    try {
      checkHemisphere(lights[i], "light " + std::to_string(i));
    } catch (const Error& e) {
      throw fail(e.what());
    }
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    try {
      checkHemisphere(views[i], "view " + std::to_string(i));
    } catch (const Error& e) {
      throw fail(e.what());
    }
  }
  if (!std::isfinite(alpha) || !(alpha > 0)) throw fail("alpha must be a finite positive number");

  kind.validate(*this, name);

  // Provenance
  for (std::size_t i = 0; i < holdoutImages.size(); ++i) {
    int h = holdoutImages[i];
    if (h < 0 || h >= numImages())
      throw fail("hold-out image index " + std::to_string(h) + " is outside [0, " + std::to_string(numImages()) + ")");
    if (i && h <= holdoutImages[i - 1]) throw fail("hold-out image indices are not strictly ascending");
  }
  checkMetadata(metadataJson, name);
}

}  // namespace nbtf
