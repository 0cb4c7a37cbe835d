// `nbtf view`: one self-contained HTML page (WebGL2, the decoder of shader_export.h and its
// textures embedded as base64; no network, no build step) that shows the material on a plane,
// a sphere and a draped cloth under a light and view moved with the mouse, with tiling and
// exposure controls and the frame time. Optionally the measured image at the nearest measured
// (light, view) pair beside it.
//
// Page modes (the URL fragment):
//   #test       renders the plane at the texel grid for viewerTestPairs() into a float
//               framebuffer and writes the linear RGB into <pre id="nbtf-result"> as JSON
//               (what the browser test compares with the C++ decoder);
//   #bench=N,F  renders the plane's default view at N x N pixels F times (after one warm-up
//               frame) and writes the median frame time there;
//   #shape=cloth&tiling=4&exposure=1&sun=1&env=0.25&scale=0.5  sets the controls.
// Everything runs synchronously while the page loads, so `chromium --headless --dump-dom`
// sees the result.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "codec/nbtf_file.h"
#include "shader/shader_export.h"

namespace nbtf {

// The measured images embedded with --reference: sRGB 8-bit RGB, image-major (image =
// light x views + view), each height x width x 3, top row first. `lights` and `views` are the
// embedded directions, a subset of the stack's `measuredLights` x `measuredViews` when all of
// them would not fit (viewerReferenceDirections).
struct ViewerReference {
  std::string name;
  int width = 0, height = 0;
  std::vector<Direction> lights, views;
  int measuredLights = 0, measuredViews = 0;  // the stack's (0: the same as embedded)
  std::string fingerprintCheck;               // the source fingerprint's verdict, shown in the page
  std::vector<std::uint8_t> srgb;
};
// The most reference bytes a page embeds (8-bit RGB before base64).
constexpr std::size_t kMaxViewerReferenceBytes = std::size_t(48) << 20;

// The lights and views (indices into `lights` and `views`) whose images a page embeds for a
// reference of `texels` texels: all of them when their 8-bit RGB fits kMaxViewerReferenceBytes,
// else the same fraction of each, spread evenly over the hemisphere (farthest-point order from
// the direction nearest the normal), the most that fit. Throws nbtf::Error when not even one
// image fits.
struct ViewerReferenceSelection {
  std::vector<int> lights, views;
};
ViewerReferenceSelection viewerReferenceDirections(const std::vector<Direction>& lights,
                                                   const std::vector<Direction>& views, std::size_t texels);

// The (light, view) pairs of the #test mode: the first and the last measured pair, and
// unmeasured pairs across the hemisphere (straight down, grazing, in between).
std::vector<std::pair<Direction, Direction>> viewerTestPairs(const CompressedBtf& material);

struct ViewerOptions {
  std::string title;                            // shown in the page (normally the file name)
  const ViewerReference* reference = nullptr;   // optional
};

// The page. Throws nbtf::Error when the reference is larger than kMaxViewerReferenceBytes.
std::string buildViewerPage(const ShaderDecoder& shader, const CompressedBtf& material, const ViewerOptions& options);

// Standard base64 (RFC 4648, with padding).
std::string base64Encode(const void* data, std::size_t size);

}  // namespace nbtf
