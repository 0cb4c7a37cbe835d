// The viewer page in a real browser: headless Chromium (Debian's `chromium`, WebGL2 on its
// software rasterizer SwiftShader) loads `nbtf view`'s page in its #test mode, which renders
// the plane at the texel grid for fixed (light, view) pairs and writes the linear RGB into the
// DOM. Every pixel must match the C++ decoder's decodeImage at the same directions to 2/255 in
// sRGB 8-bit, for a clustered, a per-texel and a PCA file. Skipped (with the reason) where
// chromium is not installed (scripts/setup.sh installs it).
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "codec/decoder.h"
#include "io/color.h"
#include "shader/viewer_page.h"
#include "shader_test_materials.h"
#include "test_util.h"

namespace nbtf {
namespace {

std::string findChromium() {
  const char* path = std::getenv("PATH");
  if (!path) return "";
  std::stringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    for (const char* name : {"chromium", "chromium-browser"}) {
      const std::filesystem::path p = std::filesystem::path(dir) / name;
      std::error_code ec;
      if (std::filesystem::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0) return p.string();
    }
  }
  return "";
}

std::string unescapeHtml(std::string s) {
  const std::pair<const char*, const char*> entities[] = {{"&lt;", "<"}, {"&gt;", ">"}, {"&quot;", "\""}, {"&amp;", "&"}};
  for (const auto& [from, to] : entities)
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + 1)) s.replace(at, std::strlen(from), to);
  return s;
}

// The DOM of `page` + `fragment` once headless chromium has loaded it.
std::string dumpDom(const std::string& chromium, const std::string& page, const std::string& scratch,
                    const std::string& fragment) {
  const std::string cmd = "timeout 120 " + chromium +
                          " --headless --no-sandbox --use-gl=angle --use-angle=swiftshader --enable-unsafe-swiftshader"
                          " --user-data-dir=" + scratch + " --dump-dom 'file://" +
                          std::filesystem::absolute(page).string() + fragment + "' 2>/dev/null";
  std::string dom;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return {};
  char buf[65536];
  std::size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) dom.append(buf, n);
  pclose(p);
  return dom;
}

// Loads page#test in headless chromium and returns the JSON the page wrote.
nlohmann::json runPage(const std::string& chromium, const std::string& page, const std::string& scratch) {
  const std::string dom = dumpDom(chromium, page, scratch, "#test");
  const std::string open = "<pre id=\"nbtf-result\">";
  const auto begin = dom.find(open);
  if (begin == std::string::npos) return {{"status", "no result element in the DOM"}, {"dom", dom.substr(0, 2000)}};
  const auto end = dom.find("</pre>", begin);
  const std::string text = unescapeHtml(dom.substr(begin + open.size(), end - begin - open.size()));
  if (text.empty()) return {{"status", "the page wrote no result"}};
  return nlohmann::json::parse(text);
}

void checkInBrowser(const std::string& chromium, const CompressedBtf& material, const std::string& label,
                    const std::string& viewOptions = "") {
  SCOPED_TRACE(label);
  test::TempDir tmp;
  const std::string file = tmp / (label + ".nbtf"), page = tmp / "viewer.html";
  writeNbtf(file, material);
  const auto made = test::runNbtf("view " + file + " -o " + page + " -q " + viewOptions);
  ASSERT_EQ(made.exitCode, 0) << made.output;
  const nlohmann::json r = runPage(chromium, page, tmp / "profile");
  ASSERT_EQ(r.value("status", ""), "ok") << r.dump().substr(0, 4000);
  ASSERT_EQ(r["width"], material.width);
  ASSERT_EQ(r["height"], material.height);
  // The reference reads the file back, as the page's generator did (compact parts rounded).
  const NbtfDecoder decoder = NbtfDecoder::open(file);
  const auto pairs = viewerTestPairs(material);
  ASSERT_EQ(r["pairs"].size(), pairs.size());
  const std::size_t values = 3 * static_cast<std::size_t>(material.numTexels());
  std::vector<float> want(values);
  std::size_t informative = 0, total = 0;  // values inside (0.01, 0.99): not clamped away in 8 bits
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const auto& [light, view] = pairs[i];
    decoder.decodeImage(light, view, want.data());
    for (float w : want) informative += w > 0.01f && w < 0.99f, ++total;
    const auto& got = r["pairs"][i]["rgb"];
    ASSERT_EQ(got.size(), values);
    int worst = 0;
    double worstLinear = 0;
    std::size_t at = 0, differing = 0;
    for (std::size_t k = 0; k < values; ++k) {
      const float g = got[k].get<float>();
      const int d = std::abs(int(linearToSrgb8(g)) - int(linearToSrgb8(want[k])));
      if (d > worst) worst = d, at = k;
      differing += d > 0;
      worstLinear = std::max(worstLinear, std::abs(double(g) - want[k]));
    }
    const int texel = static_cast<int>(at / 3);
    EXPECT_LE(worst, 2) << "pair " << i << ": light " << formatDirection(light) << ", view " << formatDirection(view)
                        << ": texel (" << texel % material.width << ", " << texel / material.width << ") channel "
                        << at % 3 << " is " << got[at].get<float>() << " in the browser, " << want[at] << " in C++";
    // For the record (not a criterion): how far the float values are apart.
    ::testing::Test::RecordProperty(label + "_pair" + std::to_string(i) + "_max_linear_diff", std::to_string(worstLinear));
    ::testing::Test::RecordProperty(label + "_pair" + std::to_string(i) + "_srgb8_values_differing", std::to_string(differing));
  }
  EXPECT_GT(informative, total / 2) << "the material's values are mostly clamped in 8 bits: a weak comparison";
}

class ViewerBrowser : public ::testing::Test {
 protected:
  void SetUp() override {
    chromium_ = findChromium();
    if (chromium_.empty())
      GTEST_SKIP() << "chromium is not on the PATH: the viewer's browser test needs Debian's chromium "
                      "(scripts/setup.sh installs it); skipped";
  }
  std::string chromium_;
};

TEST_F(ViewerBrowser, ClusteredPageMatchesTheDecoder) {
  // Stored as `nbtf compress` stores it: 8-bit decoder weights, half latents, zstd-coded ids.
  CompressedBtf m = testing::makeShaderClusteredMaterial();
  m.storage.decoderInt8 = m.storage.latentsHalf = m.storage.idsZstd = true;
  roundToStorage(m);
  checkInBrowser(chromium_, m, "clustered");  // weights in uniform blocks (they fit)
}

TEST_F(ViewerBrowser, ClusterPlanesPageMatchesTheDecoder) {
  // configs/high_fidelity.json's storage: cluster planes as 8-bit codes, read back as the file holds them.
  CompressedBtf m = testing::makeShaderClusteredMaterial(5);
  m.storage.decoderInt8 = m.storage.latentsHalf = m.storage.idsZstd = m.storage.clusterPlanes8Bit = true;
  roundToStorage(m);
  checkInBrowser(chromium_, m, "cluster-planes", "--weights texture");
}

TEST_F(ViewerBrowser, PerTexelPageMatchesTheDecoder) {
  checkInBrowser(chromium_, testing::makeShaderPerTexelMaterial(), "per-texel", "--weights texture");
}

TEST_F(ViewerBrowser, PcaPageMatchesTheDecoder) {
  checkInBrowser(chromium_, testing::makeShaderPcaMaterial(), "pca");
}

// The interactive page: its status line gives the light in the material's frame, labelled, and
// the result line of the test modes is not shown (in #test it is).
TEST_F(ViewerBrowser, TheInteractivePageSpeaksInTheMaterialsFrameAndHidesTheTestResult) {
  test::TempDir tmp;
  const std::string file = tmp / "pt.nbtf", page = tmp / "viewer.html";
  writeNbtf(file, testing::makeShaderPerTexelMaterial());
  ASSERT_EQ(test::runNbtf("view " + file + " -o " + page + " -q").exitCode, 0);
  const std::string dom = dumpDom(chromium_, page, tmp / "profile", "");
  EXPECT_NE(dom.find("light (45\u00b0, 60\u00b0) in the material's frame (theta from the normal, phi from the "
                     "texture's u axis)"),
            std::string::npos)
      << dom.substr(0, 3000);
  EXPECT_NE(dom.find("<body>"), std::string::npos) << "the result line is shown outside the test modes";
  EXPECT_NE(dumpDom(chromium_, page, tmp / "profile", "#test").find("<body class=\"results\">"), std::string::npos);
}

}  // namespace
}  // namespace nbtf
