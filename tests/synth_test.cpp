// Tests of the synthetic material generator: the renderer's physics, determinism, and the
// files it writes (UBO2003 JPEG, UTIA PNG and EXR) read back through the real loader.
#include "synth/synth_material.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>

#include <sys/wait.h>

#include "io/btf_loader.h"
#include "io/btf_names.h"
#include "io/color.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf::synth {
namespace {
namespace fs = std::filesystem;

// A fresh folder under the test temp dir, removed afterwards.
class TempDir {
 public:
  explicit TempDir(const std::string& name) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::path(::testing::TempDir()) / ("nbtf_synth_" + std::string(info->name()) + "_" + name);
    fs::remove_all(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string str() const { return path_.string(); }
  fs::path path() const { return path_; }

 private:
  fs::path path_;
};

std::vector<float> renderImage(const SynthMaterial& m, const Direction& l, const Direction& v) {
  std::vector<float> rgb(static_cast<std::size_t>(m.width()) * m.height() * 3);
  m.render(l, v, rgb.data());
  return rgb;
}

double mean(const std::vector<float>& v) { return std::accumulate(v.begin(), v.end(), 0.0) / v.size(); }

SynthOptions smallOptions(Layout layout, ImageFormat format, std::uint64_t seed = 7) {
  SynthOptions o;
  o.preset = "fabric";
  o.width = o.height = 8;
  o.seed = seed;
  o.layout = layout;
  o.format = format;
  o.progress = false;
  return o;
}

class QuietProgress : public ::testing::Environment {
 public:
  void SetUp() override { Progress::setQuiet(true); }
};
const auto* const kQuiet = ::testing::AddGlobalTestEnvironment(new QuietProgress);

// ---- Presets and options --------------------------------------------------------------

TEST(SynthPresets, ListsTheRequiredPresetsWithDescriptions) {
  std::vector<std::string> names = presetNames();
  for (const char* required : {"fabric", "wool", "glossy", "corduroy", "satin"})
    EXPECT_NE(std::find(names.begin(), names.end(), required), names.end()) << required;
  EXPECT_EQ(names.front(), "fabric");  // the default material
  for (const auto& n : names) EXPECT_GT(presetDescription(n).size(), 20u) << n;
  try {
    presetDescription("velvet");
    FAIL() << "unknown preset accepted";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("velvet"), std::string::npos) << msg;
    EXPECT_NE(msg.find("fabric"), std::string::npos) << msg;  // says what is available
  }
}

TEST(SynthPresets, RejectsBadMaterialParameters) {
  EXPECT_THROW(SynthMaterial("nope", 8, 8, 1), Error);
  EXPECT_THROW(SynthMaterial("fabric", 0, 8, 1), Error);
  EXPECT_THROW(SynthMaterial("fabric", 8, 0, 1), Error);
  EXPECT_THROW(SynthMaterial("fabric", kMinSize - 1, 8, 1), Error);
  EXPECT_THROW(SynthMaterial("fabric", 8, kMaxSize + 1, 1), Error);
  RenderSettings s;
  s.supersampling = 0;
  EXPECT_THROW(SynthMaterial("fabric", 8, 8, 1, s), Error);
  s.supersampling = 5;
  EXPECT_THROW(SynthMaterial("fabric", 8, 8, 1, s), Error);
  SynthMaterial m("fabric", 8, 8, 1);
  std::vector<float> rgb(8 * 8 * 3);
  EXPECT_THROW(m.render({91, 0}, {0, 0}, rgb.data()), Error);  // light below the horizon
  EXPECT_THROW(m.render({0, 0}, {-5, 0}, rgb.data()), Error);
}

TEST(SynthOptionsCheck, RejectsBadLayoutFormatPairsAndSizes) {
  // UBO2003 ships as JPEG only; UTIA as PNG or EXR.
  EXPECT_NO_THROW(validateSynthOptions(smallOptions(Layout::Ubo2003, ImageFormat::Jpg)));
  EXPECT_NO_THROW(validateSynthOptions(smallOptions(Layout::Utia, ImageFormat::Png)));
  EXPECT_NO_THROW(validateSynthOptions(smallOptions(Layout::Utia, ImageFormat::Exr)));
  EXPECT_THROW(validateSynthOptions(smallOptions(Layout::Ubo2003, ImageFormat::Exr)), Error);
  EXPECT_THROW(validateSynthOptions(smallOptions(Layout::Ubo2003, ImageFormat::Png)), Error);
  EXPECT_THROW(validateSynthOptions(smallOptions(Layout::Utia, ImageFormat::Jpg)), Error);
  EXPECT_THROW(validateSynthOptions(smallOptions(Layout::Unknown, ImageFormat::Png)), Error);
  SynthOptions o = smallOptions(Layout::Ubo2003, ImageFormat::Jpg);
  o.width = 0;
  EXPECT_THROW(validateSynthOptions(o), Error);
  o = smallOptions(Layout::Ubo2003, ImageFormat::Jpg);
  o.preset = "nope";
  EXPECT_THROW(validateSynthOptions(o), Error);
}

// ---- Rendering: determinism ------------------------------------------------------------

TEST(SynthRender, DeterministicForASeedOnAnyThreadCount) {
  const Direction l{45, 40}, v{30, 210};
  for (const std::string& preset : presetNames()) {
    setThreadCount(1);
    std::vector<float> a = renderImage(SynthMaterial(preset, 24, 16, 5), l, v);
    setThreadCount(2);
    std::vector<float> b = renderImage(SynthMaterial(preset, 24, 16, 5), l, v);
    std::vector<float> c = renderImage(SynthMaterial(preset, 24, 16, 6), l, v);
    EXPECT_EQ(a, b) << preset << ": same seed, different thread count";
    EXPECT_NE(a, c) << preset << ": different seeds gave the same material";
  }
  setThreadCount(0);
}

TEST(SynthRender, BatchPassesEqualSingleRender) {
  SynthMaterial m("wool", 16, 16, 3);
  auto light = m.prepareLight({60, 72});
  auto view = m.prepareView({45, 140});
  std::vector<float> batch(16 * 16 * 3);
  m.render(*light, *view, batch.data());
  EXPECT_EQ(batch, renderImage(m, {60, 72}, {45, 140}));
}

// ---- Rendering: physics ------------------------------------------------------------------

TEST(SynthRender, ValuesAreFiniteNonNegativeAndMostlyBelowOne) {
  // Over the whole 81 x 81 stack: only highlights exceed 1 (and clip in 8-bit files).
  const auto& dirs = hemisphere81();
  for (const std::string& preset : presetNames()) {
    SynthMaterial m(preset, 8, 8, 1);
    std::vector<std::shared_ptr<const SynthMaterial::LightPass>> lights;
    for (const Direction& l : dirs) lights.push_back(m.prepareLight(l));
    std::vector<float> rgb(8 * 8 * 3);
    std::size_t above = 0, total = 0;
    for (const Direction& v : dirs) {
      auto view = m.prepareView(v);
      for (const auto& light : lights) {
        m.render(*light, *view, rgb.data());
        for (float x : rgb) {
          ASSERT_TRUE(std::isfinite(x) && x >= 0) << preset << " value " << x;
          above += x > 1, ++total;
        }
      }
    }
    EXPECT_LT(static_cast<double>(above) / total, 0.02) << preset;
    double frontal = mean(renderImage(m, {0, 0}, {0, 0}));
    EXPECT_GT(frontal, 0.02) << preset << " is nearly black under frontal light";
    EXPECT_LT(frontal, 0.9) << preset;
  }
}

TEST(SynthRender, GrazingLightIsDarkerThanNormalLight) {
  // The cos(theta_l) falloff plus shadowing: every preset, averaged over the texels and
  // over the azimuths of the grazing ring.
  for (const std::string& preset : presetNames()) {
    SynthMaterial m(preset, 16, 16, 2);
    double normal = mean(renderImage(m, {0, 0}, {0, 0}));
    double grazing = 0;
    for (int i = 0; i < 24; i += 3) grazing += mean(renderImage(m, {75, 15.0 * i}, {0, 0})) / 8;
    EXPECT_LT(grazing, 0.6 * normal) << preset;
  }
}

TEST(SynthRender, SelfShadowingDarkensTexelsUnderGrazingLight) {
  RenderSettings noShadows;
  noShadows.shadows = false;
  for (const std::string& preset : {"fabric", "wool", "corduroy"}) {
    SynthMaterial shadowed(preset, 32, 32, 4), open(preset, 32, 32, 4, noShadows);
    std::vector<float> a = renderImage(shadowed, {75, 0}, {0, 0}), b = renderImage(open, {75, 0}, {0, 0});
    std::size_t darker = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_LE(a[i], b[i] + 1e-6f) << preset << ": shadowing brightened sample " << i;
      darker += a[i] < 0.5f * b[i];
    }
    // A good share of the texels lies in shadow at 75 degrees (wool: most of it).
    EXPECT_GT(darker, a.size() / 10) << preset;
    // Light from straight above casts no shadows on a height field.
    EXPECT_EQ(renderImage(shadowed, {0, 0}, {30, 90}), renderImage(open, {0, 0}, {30, 90})) << preset;
  }
}

TEST(SynthRender, WoolOccludesMoreThanFabric) {
  // The knit preset is the strongly occluding one: under grazing light a larger share of
  // its texels loses most of its unshadowed value.
  RenderSettings noShadows;
  noShadows.shadows = false;
  auto shadowedShare = [&](const char* preset) {
    SynthMaterial a(preset, 36, 36, 1), b(preset, 36, 36, 1, noShadows);
    std::size_t dark = 0, total = 0;
    for (double phi : {0.0, 90.0, 180.0, 270.0}) {
      std::vector<float> s = renderImage(a, {60, phi}, {0, 0}), o = renderImage(b, {60, phi}, {0, 0});
      for (std::size_t i = 0; i < s.size(); ++i) dark += s[i] < 0.5f * o[i], ++total;
    }
    return static_cast<double>(dark) / total;
  };
  EXPECT_GT(shadowedShare("wool"), shadowedShare("fabric"));
}

// Mean green value of the texels whose height slopes toward / away from the light, with
// the light straight along x (alongX) or along y. Shadows and parallax off: pure shading.
std::pair<double, double> brightnessBySlope(const SynthMaterial& m, const Direction& light, bool alongX) {
  const int w = m.width(), h = m.height();
  std::vector<float> height = m.heightMap();
  std::vector<float> rgb = renderImage(m, light, {0, 0});
  double lit = 0, unlit = 0;
  int nLit = 0, nUnlit = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // Height rising toward +x: the face looks to -x. Rising toward the bottom row: it
      // looks up (+y), since rows run down the image.
      float slope = alongX ? height[y * w + (x + 1) % w] - height[y * w + (x + w - 1) % w]
                           : height[((y + 1) % h) * w + x] - height[((y + h - 1) % h) * w + x];
      if (std::fabs(slope) < 0.3f) continue;
      bool facesPositive = alongX ? slope < 0 : slope > 0;
      double value = rgb[(y * w + x) * 3 + 1];
      (facesPositive ? lit : unlit) += value;
      (facesPositive ? nLit : nUnlit) += 1;
    }
  EXPECT_GT(nLit, 10);
  EXPECT_GT(nUnlit, 10);
  return {lit / std::max(1, nLit), unlit / std::max(1, nUnlit)};
}

TEST(SynthRender, FacesTurnedTowardTheLightAreBrighter) {
  // Frame convention: phi = 0 lights from the image's right (+x), phi = 90 from its top.
  RenderSettings shadingOnly;
  shadingOnly.shadows = false;
  shadingOnly.parallax = false;
  SynthMaterial corduroy("corduroy", 44, 44, 1, shadingOnly);
  auto [rightFacing, leftFacing] = brightnessBySlope(corduroy, {60, 0}, true);
  EXPECT_GT(rightFacing, 1.5 * leftFacing);
  auto [rightFacing2, leftFacing2] = brightnessBySlope(corduroy, {60, 180}, true);
  EXPECT_LT(rightFacing2, 0.67 * leftFacing2);
  SynthMaterial wool("wool", 36, 39, 1, shadingOnly);
  auto [upFacing, downFacing] = brightnessBySlope(wool, {60, 90}, false);
  EXPECT_GT(upFacing, 1.2 * downFacing);
  auto [upFacing2, downFacing2] = brightnessBySlope(wool, {60, 270}, false);
  EXPECT_LT(upFacing2, downFacing2 / 1.2);
}

TEST(SynthRender, ParallaxOnlyMattersForObliqueViews) {
  RenderSettings flat;
  flat.parallax = false;
  SynthMaterial withParallax("fabric", 24, 24, 3), without("fabric", 24, 24, 3, flat);
  // Straight down, the view ray hits the texel below and nothing masks it.
  EXPECT_EQ(renderImage(withParallax, {30, 60}, {0, 0}), renderImage(without, {30, 60}, {0, 0}));
  EXPECT_NE(renderImage(withParallax, {30, 60}, {60, 0}), renderImage(without, {30, 60}, {60, 0}));
}

TEST(SynthRender, PatternTilesWithoutSeams) {
  // Across the wrap-around (last column -> first) the height changes no more than between
  // neighbouring columns inside the tile.
  for (const std::string& preset : presetNames()) {
    SynthMaterial m(preset, 40, 34, 9);
    const int w = m.width(), h = m.height();
    std::vector<float> hm = m.heightMap();
    double inside = 0, seamX = 0, seamY = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x + 1 < w; ++x) inside += std::fabs(hm[y * w + x + 1] - hm[y * w + x]) / ((w - 1.0) * h);
      seamX += std::fabs(hm[y * w] - hm[y * w + w - 1]) / h;
    }
    for (int x = 0; x < w; ++x) seamY += std::fabs(hm[x] - hm[(h - 1) * w + x]) / w;
    EXPECT_LT(seamX, 2.5 * inside) << preset;
    EXPECT_LT(seamY, 2.5 * inside) << preset;
  }
}

// ---- Writing and reading back -----------------------------------------------------------

// Every ground-truth image of a written stack, in stack order (light * 81 + view).
std::vector<std::vector<float>> allGroundTruth(const std::string& dir) {
  std::vector<std::vector<float>> out;
  for (int l = 0; l < 81; ++l)
    for (int v = 0; v < 81; ++v) out.push_back(readGroundTruthImage(dir, l, v));
  return out;
}

// Each test below writes full 6561-image stacks (8 x 8 texels): ctest runs every test in
// its own process, so each generates what it checks, at most twice.

TEST(SynthWrite, Ubo2003JpegIsDeterministicAndRoundTripsThroughTheLoader) {
  TempDir a("a"), b("b");
  SynthOptions o = smallOptions(Layout::Ubo2003, ImageFormat::Jpg, 3);
  setThreadCount(2);
  SynthSummary summary = writeSynthStack(o, a.str());
  setThreadCount(1);
  writeSynthStack(o, b.str());
  setThreadCount(0);
  EXPECT_EQ(summary.images, 6561);
  EXPECT_EQ(summary.groundTruthFiles, 81);

  // Same seed, any thread count: byte-identical files (images, ground truth, synth.json).
  std::size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a.path())) {
    if (!e.is_regular_file()) continue;
    fs::path rel = fs::relative(e.path(), a.path());
    ASSERT_EQ(readFileBytes(e.path().string()), readFileBytes((b.path() / rel).string())) << rel;
    ++files;
  }
  EXPECT_EQ(files, 6561u + 81u + 1u);

  // The on-disk layout is exactly UBO2003's: one folder per view, indexed names.
  const auto& dirs = hemisphere81();
  for (int v : {0, 40, 80})
    for (int l : {0, 7, 80}) {
      fs::path file = a.path() / viewFolderName(dirs[v]) / ubo2003FileName(81 * l + v, dirs[l], dirs[v], ".jpg");
      EXPECT_TRUE(fs::is_regular_file(file)) << file;
    }
  EXPECT_TRUE(fs::is_regular_file(a.path() / "tv045_pv100" / "01806 tl045 pl060 tv045 pv100.jpg"));
  LoadOptions lo;
  lo.progress = false;
  BtfStack stack = loadBtfStack(a.str(), lo);
  EXPECT_EQ(stack.layout, Layout::Ubo2003);
  ASSERT_EQ(stack.numImages(), 6561);
  EXPECT_EQ(stack.lights(), dirs);
  EXPECT_EQ(stack.views(), dirs);
  EXPECT_EQ(stack.width(), 8);

  // Tolerance, in 8-bit sRGB code values against the quantized ground truth: JPEG
  // quality 95 with OpenCV's 4:2:0 chroma subsampling on the saturated, fine thread
  // structure. Measured for this stack: mean 4.5, 99th percentile 21, max 38 codes.
  auto truth = allGroundTruth(a.str());
  double sum = 0;
  std::size_t count = 0, over30 = 0;
  int worst = 0;
  for (int i = 0; i < stack.numImages(); ++i) {
    const std::uint8_t* bytes = stack.imageBytes(i);
    for (std::size_t k = 0; k < truth[i].size(); ++k) {
      int diff = std::abs(static_cast<int>(bytes[k]) - static_cast<int>(linearToSrgb8(truth[i][k])));
      sum += diff, ++count, over30 += diff > 30;
      worst = std::max(worst, diff);
    }
  }
  EXPECT_LE(sum / count, 6.0);
  EXPECT_LE(static_cast<double>(over30) / count, 0.01);
  EXPECT_LE(worst, 64);
}

TEST(SynthWrite, UtiaPngIsTheQuantizedGroundTruthAndJsonDescribesIt) {
  TempDir dir("png");
  SynthOptions o = smallOptions(Layout::Utia, ImageFormat::Png, 11);
  o.preset = "glossy";
  SynthSummary summary = writeSynthStack(o, dir.str());
  LoadOptions lo;
  lo.progress = false;
  BtfStack stack = loadBtfStack(dir.str(), lo);
  EXPECT_EQ(stack.layout, Layout::Utia);
  ASSERT_EQ(stack.numImages(), 6561);
  EXPECT_TRUE(fs::is_regular_file(dir.path() / "tv075_pv345" / "tl015_pl060_tv075_pv345.png"));

  // PNG is lossless: every byte is the 8-bit sRGB quantization of the float ground truth
  // (clipped above 1), so the linear error is within half a quantization step.
  auto truth = allGroundTruth(dir.str());
  for (int i = 0; i < stack.numImages(); ++i) {
    const std::uint8_t* bytes = stack.imageBytes(i);
    for (std::size_t k = 0; k < truth[i].size(); ++k)
      ASSERT_EQ(bytes[k], linearToSrgb8(truth[i][k])) << "image " << i << " sample " << k << " value " << truth[i][k];
  }

  // The ground truth is exactly the renderer's output.
  SynthMaterial m("glossy", 8, 8, 11);
  const auto& dirs = hemisphere81();
  for (auto [l, v] : {std::pair{0, 0}, {12, 47}, {80, 80}, {44, 3}})
    EXPECT_EQ(truth[81 * l + v], renderImage(m, dirs[l], dirs[v])) << l << "," << v;

  // A ground-truth file: 81 light images stacked vertically, linear float.
  ImageF gt = readExr((dir.path() / "ground_truth" / (viewFolderName(dirs[5]) + ".exr")).string());
  EXPECT_EQ(gt.width, 8);
  EXPECT_EQ(gt.height, 81 * 8);
  std::vector<float> block(gt.rgb.begin() + 3 * 8 * 8 * 9, gt.rgb.begin() + 3 * 8 * 8 * 10);
  EXPECT_EQ(block, truth[81 * 9 + 5]);

  std::ifstream in(dir.path() / "synth.json");
  nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("preset"), "glossy");
  EXPECT_EQ(j.at("width"), 8);
  EXPECT_EQ(j.at("height"), 8);
  EXPECT_EQ(j.at("seed"), 11);
  EXPECT_EQ(j.at("layout"), "utia");
  EXPECT_EQ(j.at("format"), "png");
  EXPECT_EQ(j.at("complete"), true);
  EXPECT_EQ(j.at("lights").size(), 81u);
  EXPECT_EQ(j.at("views").at(80), nlohmann::json::array({75.0, 345.0}));
  EXPECT_FALSE(j.at("description").get<std::string>().empty());
  float lo2 = 1e30f, hi = -1e30f;
  for (const auto& img : truth)
    for (float x : img) lo2 = std::min(lo2, x), hi = std::max(hi, x);
  EXPECT_FLOAT_EQ(j.at("values").at("min").get<float>(), lo2);
  EXPECT_FLOAT_EQ(j.at("values").at("max").get<float>(), hi);
  EXPECT_FLOAT_EQ(summary.maxValue, hi);
  EXPECT_GT(hi, 1.0f);  // the glossy preset's highlights exceed 1 (they clip in 8-bit)

  EXPECT_THROW(readGroundTruthImage(dir.str(), 81, 0), Error);
  EXPECT_THROW(readGroundTruthImage(dir.str(), 0, -1), Error);
  EXPECT_THROW(readGroundTruthImage((dir.path() / "missing").string(), 0, 0), Error);
}

TEST(SynthWrite, UtiaExrRoundTripWithinHalfPrecisionAfterXyz) {
  TempDir dir("exr");
  writeSynthStack(smallOptions(Layout::Utia, ImageFormat::Exr), dir.str());
  EXPECT_TRUE(fs::is_regular_file(dir.path() / "tv030_pv150" / "tl060_pl018_tv030_pv150.exr"));
  LoadOptions lo;
  lo.progress = false;
  BtfStack stack = loadBtfStack(dir.str(), lo);  // UTIA EXR: CIE XYZ, converted back to linear sRGB
  EXPECT_EQ(stack.sampleType(), SampleType::Half);
  ASSERT_EQ(stack.numImages(), 6561);
  // Half keeps 11 significant bits (relative error <= 2^-11 per XYZ value); the XYZ ->
  // sRGB matrix (row sums of |coefficients| <= 5.3) turns that into at most
  // 5.3 * 2^-11 * 1.09 * max(R, G, B) ~ 2.8e-3 * max per channel; the loader stores the
  // result as half again (+2.4e-4 relative) and half's absolute floor is ~6e-8.
  auto truth = allGroundTruth(dir.str());
  std::vector<float> img(8 * 8 * 3);
  double worstRelative = 0;
  for (int i = 0; i < stack.numImages(); ++i) {
    stack.imageLinear(i, img.data());
    for (std::size_t t = 0; t < img.size(); t += 3) {
      float peak = std::max({truth[i][t], truth[i][t + 1], truth[i][t + 2]});
      for (int c = 0; c < 3; ++c) {
        float err = std::fabs(img[t + c] - truth[i][t + c]);
        ASSERT_LE(err, 3.5e-3f * peak + 1e-6f) << "image " << i << " texel " << t / 3 << " channel " << c;
        if (peak > 0.01f) worstRelative = std::max(worstRelative, static_cast<double>(err / peak));
      }
    }
  }
  EXPECT_GT(worstRelative, 0);  // the files really are half precision, not float
}

TEST(SynthWrite, RefusesForeignFoldersAndReplacesItsOwnOutput) {
  TempDir dir("replace");
  fs::create_directories(dir.path());
  {
    std::ofstream(dir.path() / "notes.txt") << "mine";
  }
  // A non-empty folder that nbtf-synth did not write: refused, nothing written.
  EXPECT_THROW(writeSynthStack(smallOptions(Layout::Utia, ImageFormat::Png), dir.str()), Error);
  EXPECT_FALSE(fs::exists(dir.path() / "synth.json"));
  // An output path that is a file.
  EXPECT_THROW(writeSynthStack(smallOptions(Layout::Utia, ImageFormat::Png), (dir.path() / "notes.txt").string()),
               Error);
  fs::remove(dir.path() / "notes.txt");

  writeSynthStack(smallOptions(Layout::Utia, ImageFormat::Png), dir.str());
  {
    std::ofstream(dir.path() / "notes.txt") << "mine";
  }
  // Leftover of an interrupted write: a hidden temporary beside the final name, which
  // still carries the angle tokens. The loader must not take it for a duplicate image.
  fs::path leftover = dir.path() / "tv000_pv000" / ".tl000_pl000_tv000_pv000.png.tmp99_1.png";
  fs::copy_file(dir.path() / "tv000_pv000" / "tl000_pl000_tv000_pv000.png", leftover);
  LoadOptions lo;
  lo.progress = false;
  EXPECT_EQ(loadBtfStack(dir.str(), lo).numImages(), 6561);

  // Writing another layout into it replaces the earlier stack completely.
  SynthOptions again = smallOptions(Layout::Ubo2003, ImageFormat::Jpg);
  again.groundTruth = false;
  writeSynthStack(again, dir.str());
  BtfStack stack = loadBtfStack(dir.str(), lo);
  EXPECT_EQ(stack.layout, Layout::Ubo2003);
  EXPECT_EQ(stack.numImages(), 6561);
  EXPECT_FALSE(fs::exists(leftover));
  EXPECT_FALSE(fs::exists(dir.path() / "ground_truth"));  // the earlier ground truth went with its stack
  std::size_t pngs = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir.path())) pngs += e.path().extension() == ".png";
  EXPECT_EQ(pngs, 0u);
  EXPECT_TRUE(fs::exists(dir.path() / "notes.txt"));  // never deletes what it did not write
  EXPECT_THROW(readGroundTruthImage(dir.str(), 0, 0), Error);
}

// ---- The command line -------------------------------------------------------------------

int runSynth(const std::string& args, std::string* output = nullptr) {
  TempDir log("log");
  fs::create_directories(log.path());
  std::string logFile = (log.path() / "out.txt").string();
  int status = std::system((std::string(NBTF_BIN_DIR) + "/nbtf-synth " + args + " > '" + logFile + "' 2>&1").c_str());
  if (output) {
    std::ifstream in(logFile);
    std::stringstream s;
    s << in.rdbuf();
    *output = s.str();
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(SynthCli, ListsPresetsAndRejectsBadOptions) {
  std::string out;
  ASSERT_EQ(runSynth("--list-presets", &out), 0) << out;
  for (const std::string& name : presetNames()) EXPECT_NE(out.find(name), std::string::npos) << out;
  TempDir dir("cli");
  const std::string o = " -q -o '" + dir.str() + "'";
  EXPECT_EQ(runSynth("--preset velvet --size 8x8" + o, &out), 1);
  EXPECT_NE(out.find("unknown preset 'velvet'"), std::string::npos) << out;
  EXPECT_EQ(runSynth("--size 0x8" + o, &out), 1);
  EXPECT_NE(out.find("--size"), std::string::npos) << out;
  EXPECT_EQ(runSynth("--size 8by8" + o, &out), 1);
  EXPECT_EQ(runSynth("--size 4x4" + o, &out), 1);
  EXPECT_NE(out.find("out of range"), std::string::npos) << out;
  EXPECT_EQ(runSynth("--size 8x8 --layout ubo2003 --format exr" + o, &out), 1);
  EXPECT_NE(out.find("JPEG only"), std::string::npos) << out;
  EXPECT_EQ(runSynth("--size 8x8 --layout bonn" + o, &out), 1);
  EXPECT_EQ(runSynth("--size 8x8", &out), 1);  // no -o
  EXPECT_NE(out.find("-o"), std::string::npos) << out;
  EXPECT_EQ(runSynth("--size 8x8 -q -o ''", &out), 1);
  EXPECT_NE(out.find("empty"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir.path()));  // nothing written by any rejected run
}

TEST(SynthCli, WritesALoadableStack) {
  TempDir dir("cli_ok");
  std::string out;
  ASSERT_EQ(runSynth("--preset wool --size 8x10 --layout utia --format exr --seed 3 -q -o '" + dir.str() + "'", &out),
            0)
      << out;
  EXPECT_NE(out.find("wrote 6561 images"), std::string::npos) << out;
  EXPECT_NE(out.find("linear sRGB"), std::string::npos) << out;
  LoadOptions lo;
  lo.progress = false;
  BtfStack stack = loadBtfStack(dir.str(), lo);
  EXPECT_EQ(stack.width(), 8);
  EXPECT_EQ(stack.height(), 10);
  EXPECT_EQ(stack.layout, Layout::Utia);
  // The CLI and the library make the same material.
  EXPECT_EQ(readGroundTruthImage(dir.str(), 30, 60),
            renderImage(SynthMaterial("wool", 8, 10, 3), hemisphere81()[30], hemisphere81()[60]));
}

}  // namespace
}  // namespace nbtf::synth
