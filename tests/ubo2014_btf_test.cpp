#include "io/ubo2014_btf.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

#include "io/btf_loader.h"
#include "test_util.h"
#include "util/error.h"
#include "util/half.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

namespace fs = std::filesystem;

// A small material: 3 lights x 2 views, 4 x 3 texels, k components, values already half-exact.
Ubo2014Btf smallMaterial(std::int32_t colorModel = 0, int k = 2, bool abrdfsInU = true, int width = 4, int height = 3) {
  Ubo2014Meta m;
  m.lights = {{0, 0}, {30, 90}, {60, 210}};
  m.views = {{11, 15}, {45, 300}};
  m.width = width, m.height = height;
  m.colorModel = colorModel;
  m.measurementSetup = "test";
  m.xml = "<material/>";
  const int pairs = 6, texels = width * height;
  std::vector<Ubo2014Channel> channels(3);
  for (int c = 0; c < 3; ++c) {
    Ubo2014Channel& ch = channels[c];
    ch.components = k;
    ch.uRows = abrdfsInU ? pairs : texels;
    ch.sxvRows = abrdfsInU ? texels : pairs;
    for (int j = 0; j < k; ++j) ch.s.push_back(roundToHalf(3.0f - j));
    for (int i = 0; i < ch.uRows * k; ++i) ch.u.push_back(roundToHalf(0.1f + 0.05f * ((i * 7 + c * 3) % 11) / 11.0f));
    for (int i = 0; i < ch.sxvRows * k; ++i) ch.sxv.push_back(roundToHalf(0.2f + 0.3f * ((i * 5 + c) % 13) / 13.0f));
  }
  return Ubo2014Btf(m, channels, "small");
}

float dot(const std::vector<float>& a, int rowA, const std::vector<float>& b, int rowB, int k) {
  float s = 0;
  for (int j = 0; j < k; ++j) s += a[rowA * k + j] * b[rowB * k + j];
  return s;
}

TEST(Ubo2014Btf, Dome151IsBonnsSampling) {
  const auto& d = dome151();
  ASSERT_EQ(d.size(), 151u);
  EXPECT_EQ(d[0], (Direction{0, 0}));
  EXPECT_EQ(d[1], (Direction{11, 15}));     // ring 2: offset 15, 6 directions
  EXPECT_EQ(d[7], (Direction{23.5, 0}));    // ring 3 starts at index 1 + 6
  EXPECT_EQ(d[150], (Direction{75, 345}));  // last of 24 on the outer ring
  int ring75 = 0;
  for (const Direction& x : d) ring75 += x.thetaDeg == 75;
  EXPECT_EQ(ring75, 24);
}

TEST(Ubo2014Btf, AbrdfIsARowOfUTimesSxV) {
  Ubo2014Btf btf = smallMaterial();
  const int nl = 3, nv = 2, k = 2;
  std::vector<float> abrdf(btf.numImages() * 3);
  const int texel = 7;  // x 3, y 1
  btf.abrdfLinear(texel, abrdf.data());
  for (int l = 0; l < nl; ++l)
    for (int v = 0; v < nv; ++v)
      for (int c = 0; c < 3; ++c) {
        const auto& ch = btf.channels()[c];
        // nbtf image l * views + v is the file's row l + lights * v (light fastest).
        EXPECT_NEAR(abrdf[(l * nv + v) * 3 + c], dot(ch.u, l + nl * v, ch.sxv, texel, k), 1e-6f);
      }
  // imageLinear agrees with abrdfLinear
  std::vector<float> img(btf.numTexels() * 3);
  btf.imageLinear(1 * nv + 1, img.data());
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(img[texel * 3 + c], abrdf[(1 * nv + 1) * 3 + c], 1e-6f);
}

TEST(Ubo2014Btf, UWithTexelRowsDecodesTheSame) {
  Ubo2014Btf btf = smallMaterial(0, 2, /*abrdfsInU=*/false);
  EXPECT_FALSE(btf.abrdfsInU());
  std::vector<float> abrdf(btf.numImages() * 3);
  btf.abrdfLinear(5, abrdf.data());
  const auto& ch = btf.channels()[1];
  EXPECT_NEAR(abrdf[(2 * 2 + 1) * 3 + 1], dot(ch.sxv, 2 + 3 * 1, ch.u, 5, 2), 1e-6f);
}

TEST(Ubo2014Btf, ColorModel11IsBonnsUndecorrelation) {
  Ubo2014Btf btf = smallMaterial(11);
  std::vector<float> abrdf(btf.numImages() * 3);
  btf.abrdfLinear(0, abrdf.data());
  float v[3];
  for (int c = 0; c < 3; ++c) v[c] = dot(btf.channels()[c].u, 0, btf.channels()[c].sxv, 0, 2);
  const float eps = 1e-5f, y = std::exp(v[0]) - eps, u = v[1] * (y + eps), w = v[2] * (y + eps);
  EXPECT_NEAR(abrdf[0], y + 1.13983f * w, 1e-5f);
  EXPECT_NEAR(abrdf[1], y - 0.39465f * u - 0.5806f * w, 1e-5f);
  EXPECT_NEAR(abrdf[2], y + 2.03211f * u, 1e-5f);
}

TEST(Ubo2014Btf, WriteReadRoundTripKeepsEveryValue) {
  test::TempDir dir;
  for (std::int32_t model : {0, 11}) {
    Ubo2014Btf a = smallMaterial(model, 3);
    const std::string path = dir / ("m" + std::to_string(model) + ".btf");
    a.write(path);
    Ubo2014Btf b = Ubo2014Btf::read(path);
    EXPECT_EQ(b.meta().signature, "!DFMF08FCR");
    EXPECT_EQ(b.meta().colorModel, model);
    EXPECT_EQ(b.meta().xml, "<material/>");
    EXPECT_EQ(b.meta().measurementSetup, "test");
    EXPECT_EQ(b.width(), 4);
    EXPECT_EQ(b.height(), 3);
    ASSERT_EQ(b.meta().lights.size(), 3u);
    ASSERT_EQ(b.meta().views.size(), 2u);
    for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(b.meta().lights[i], a.meta().lights[i]);  // rounded to 1/1000 degree
    for (std::size_t i = 0; i < 2; ++i) EXPECT_EQ(b.meta().views[i], a.meta().views[i]);
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(b.channels()[c].u, a.channels()[c].u);  // half-exact values come back bit for bit
      EXPECT_EQ(b.channels()[c].sxv, a.channels()[c].sxv);
      EXPECT_EQ(b.channels()[c].s, a.channels()[c].s);
    }
    std::vector<float> ra(a.numImages() * 3), rb(b.numImages() * 3);
    for (int t = 0; t < a.numTexels(); ++t) {
      a.abrdfLinear(t, ra.data());
      b.abrdfLinear(t, rb.data());
      EXPECT_EQ(ra, rb);
    }
    // the file's size is what the format says: signature, meta data (fixed part, XML, channel
    // names), views x (angles, light count, light angles), size, rotation count, DFMF fields,
    // 3 x (channel header + half floats: k + 6 k + 12 k)
    const std::size_t meta = 4 + 4 + 240 + 4 + 12 + 4 + 4 + 11 + 4 + 3 * (4 + 1);
    EXPECT_EQ(fs::file_size(path), 10 + meta + 4 + 2 * (8 + 4 + 3 * 8) + 8 + 4 + (4 + 4 + 12 + 36) + 3 * (13 + 2 * 19 * 3));
  }
}

TEST(Ubo2014Btf, LoaderExpandsOnlyTheCrop) {
  test::TempDir dir;
  Ubo2014Btf btf = smallMaterial(0);
  const std::string path = dir / "crop.btf";
  btf.write(path);
  LoadOptions o;
  o.progress = false;
  o.crop = {1, 1, 2, 2};
  BtfStack s = loadBtfStack(path, o);
  EXPECT_EQ(s.layout, Layout::Ubo2014);
  EXPECT_EQ(s.width(), 2);
  EXPECT_EQ(s.numLights(), 3);
  EXPECT_EQ(s.numViews(), 2);
  EXPECT_EQ(s.sampleType(), SampleType::Half);
  EXPECT_EQ(s.bytesInMemory(), 4u * 6 * 3 * 2);
  EXPECT_EQ(s.sourceWidth, 4);
  std::vector<float> abrdf(btf.numImages() * 3);
  btf.abrdfLinear(2 * 4 + 2, abrdf.data());  // crop texel (1, 1) = file texel (2, 2)
  for (int i = 0; i < s.numImages(); ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(s.sample(i, 3, c), roundToHalf(std::max(0.0f, abrdf[i * 3 + c])));
  // Resolved once: the factors are read once and the description says whether they stay factorized.
  const BtfInput in = resolveBtfInput(path, o);
  ASSERT_NE(in.ubo2014, nullptr);
  EXPECT_FALSE(in.factorized);
  EXPECT_EQ(in.shape.width, 2);
  EXPECT_EQ(in.shape.type, SampleType::Half);
  EXPECT_EQ(in.sourceWidth, 4);
  EXPECT_EQ(loadBtfStack(in, o).bytesInMemory(), s.bytesInMemory());
  LoadOptions small = o;
  small.expandUpTo = 1;
  const BtfInput computed = resolveBtfInput(path, small);
  EXPECT_TRUE(computed.factorized);
  EXPECT_GT(computed.shape.computedBytes, 0u);
  EXPECT_TRUE(loadBtfStack(computed, small).isComputed());
  StackListing listing = listBtfStack(path);
  EXPECT_EQ(listing.layout, Layout::Ubo2014);
  EXPECT_EQ(listing.lights, btf.meta().lights);
  EXPECT_EQ(checkCrop(path, o).width, 2);
  o.crop = {3, 0, 2, 2};
  try {
    checkCrop(path, o);
    FAIL() << "crop outside accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("outside the 4 x 3"), std::string::npos) << e.what();
  }
}

// Images made together, a tile of texels at a time, are valueLinear's values bit for bit:
// tiles of 64 texels and a last partial one, components in blocks of 8 and a remainder.
TEST(Ubo2014Btf, ImagesLinearIsValueLinearBitForBit) {
  for (bool abrdfsInU : {true, false})
    for (std::int32_t model : {0, 11}) {
      SCOPED_TRACE("colour model " + std::to_string(model) + (abrdfsInU ? "" : ", U with texel rows"));
      const Ubo2014Btf btf = smallMaterial(model, 11, abrdfsInU, 10, 9);
      for (Crop crop : {Crop{0, 0, 10, 9}, Crop{1, 2, 7, 5}}) {
        const int texels = crop.width * crop.height;
        std::vector<float> out(static_cast<std::size_t>(texels) * 3 * 4);
        btf.imagesLinear(2, 4, crop, out.data());
        for (int i = 0; i < 4; ++i)
          for (int t = 0; t < texels; ++t) {
            float want[3];
            btf.valueLinear(2 + i, (crop.y + t / crop.width) * 10 + crop.x + t % crop.width, want);
            for (int c = 0; c < 3; ++c)
              ASSERT_EQ(out[(static_cast<std::size_t>(i) * texels + t) * 3 + c], want[c]) << "image " << 2 + i << " texel " << t;
          }
      }
      // every image at texels in any order: as ABRDFs and gathered
      std::vector<int> texels;
      for (int t = 89; t >= 0; t -= 2) texels.push_back(t);
      const int count = static_cast<int>(texels.size()), images = btf.numImages();
      std::vector<float> abrdfs(static_cast<std::size_t>(count) * images * 3), gathered(abrdfs.size());
      btf.abrdfsLinear(texels.data(), count, abrdfs.data());
      btf.gatherLinear(nullptr, 0, texels.data(), count, gathered.data());
      for (int k = 0; k < count; ++k)
        for (int i = 0; i < images; ++i) {
          float want[3];
          btf.valueLinear(i, texels[k], want);
          for (int c = 0; c < 3; ++c) {
            ASSERT_EQ(abrdfs[(static_cast<std::size_t>(k) * images + i) * 3 + c], want[c]);
            ASSERT_EQ(gathered[static_cast<std::size_t>(3 * i + c) * count + k], want[c]);
          }
        }
    }
}

// Several threads reading images of a computed stack in any order, one image per block: every
// image is the expanded one (a thread finding its block being made makes another meanwhile).
TEST(Ubo2014Btf, ComputedStackGivesEveryImageFromManyThreads) {
  auto btf = std::make_shared<const Ubo2014Btf>(smallMaterial(11, 11, true, 10, 9));
  const BtfStack stored = btf->toStack({}, false);
  const int before = threadCount();
  setThreadCount(4);
  const BtfStack computed = Ubo2014Btf::computedStack(btf, {}, /*blockBytes=*/1);
  const int images = stored.numImages(), values = stored.numTexels() * 3;
  std::vector<int> order;
  for (int round = 0; round < 20; ++round)
    for (int i = 0; i < images; ++i) order.push_back(round % 2 ? images - 1 - i : (i * 5 + round) % images);
  std::atomic<int> wrong{0};
  parallelForDynamic(order.size(), [&](std::size_t j, int) {
    std::vector<float> a(values), b(values);
    stored.imageLinear(order[j], a.data());
    computed.imageLinear(order[j], b.data());
    if (a != b) ++wrong;
    // much of one image, gathered: from its block
    std::vector<int> texels;
    for (int t = stored.numTexels() - 1; t >= 0; t -= 3) texels.push_back(t);
    std::vector<float> ga(texels.size() * 3), gb(texels.size() * 3);
    stored.gatherLinear(&order[j], 1, texels.data(), static_cast<int>(texels.size()), ga.data());
    computed.gatherLinear(&order[j], 1, texels.data(), static_cast<int>(texels.size()), gb.data());
    if (ga != gb) ++wrong;
    // as stored: a computed stack's are the floats themselves
    std::vector<std::uint8_t> raw(gb.size() * computed.storedValueBytes());
    computed.gatherStored(&order[j], 1, texels.data(), static_cast<int>(texels.size()), raw.data());
    std::vector<float> gc(gb.size());
    computed.storedToLinear(raw.data(), gc.size(), 1.0f, gc.data());
    if (gc != gb || computed.storedValueBytes() != sizeof(float)) ++wrong;
  });
  setThreadCount(before);
  EXPECT_EQ(wrong.load(), 0);
}

// A stack computed from the factors holds exactly what the expanded one stores, through every
// accessor; the loader keeps a file factorized when its expansion passes LoadOptions::expandUpTo.
TEST(Ubo2014Btf, ComputedStackHoldsTheExpandedValues) {
  for (std::int32_t model : {0, 11}) {
    SCOPED_TRACE("colour model " + std::to_string(model));
    auto btf = std::make_shared<const Ubo2014Btf>(smallMaterial(model, 2));
    for (Crop crop : {Crop{}, Crop{1, 1, 3, 2}}) {
      const BtfStack stored = btf->toStack(crop, false);
      const BtfStack computed = Ubo2014Btf::computedStack(btf, crop);
      ASSERT_FALSE(stored.isComputed());
      ASSERT_TRUE(computed.isComputed());
      EXPECT_EQ(computed.width(), stored.width());
      EXPECT_EQ(computed.crop.x, stored.crop.x);
      EXPECT_EQ(computed.sourceWidth, 4);
      EXPECT_EQ(computed.layout, Layout::Ubo2014);
      EXPECT_EQ(computed.sampleType(), SampleType::Half);
      EXPECT_EQ(computed.bytesInMemory(),
                btf->factorBytes() + ubo2014ComputedBlockBytes(computed.numTexels(), computed.numImages()));
      const int texels = stored.numTexels(), images = stored.numImages();
      std::vector<float> a(texels * 3), b(texels * 3);
      for (int i = 0; i < images; ++i) {
        stored.imageLinear(i, a.data());
        computed.imageLinear(i, b.data());
        EXPECT_EQ(a, b) << "image " << i;
        for (int t = 0; t < texels; ++t)
          for (int c = 0; c < 3; ++c) EXPECT_EQ(computed.sample(i, t, c), stored.sample(i, t, c));
      }
      EXPECT_EQ(computed.abrdfLinear(texels - 1), stored.abrdfLinear(texels - 1));
      const std::vector<int> someImages = {4, 0, 2}, someTexels = {texels - 1, 0, 1};
      std::vector<float> ga(9 * 3), gb(9 * 3);
      stored.gatherLinear(someImages.data(), 3, someTexels.data(), 3, ga.data());
      computed.gatherLinear(someImages.data(), 3, someTexels.data(), 3, gb.data());
      EXPECT_EQ(ga, gb);
      EXPECT_EQ(gb[(3 * 1 + 2) * 3 + 0], stored.sample(0, texels - 1, 2));  // (image 0, channel B) of texel texels - 1
      float lo1, hi1, lo2, hi2;
      stored.valueRange(lo1, hi1);
      computed.valueRange(lo2, hi2);
      EXPECT_EQ(lo1, lo2);
      EXPECT_EQ(hi1, hi2);
      BtfStack writable = computed;
      EXPECT_THROW(writable.imageBytes(0), Error);
    }
  }
  test::TempDir dir;
  const std::string path = dir / "big.btf";
  smallMaterial(11).write(path);
  LoadOptions o;
  o.progress = false;
  EXPECT_FALSE(loadBtfStack(path, o).isComputed());
  EXPECT_EQ(stackShape(path, o).computedBytes, 0u);
  o.expandUpTo = 12 * 6 * 6 - 1;  // one byte less than the half-float expansion
  EXPECT_TRUE(loadBtfStack(path, o).isComputed());
  EXPECT_EQ(stackShape(path, o).stackBytes(), Ubo2014Btf::read(path).factorBytes() + ubo2014ComputedBlockBytes(12, 6));
  o.crop = {0, 0, 2, 2};  // a crop small enough is expanded
  EXPECT_FALSE(loadBtfStack(path, o).isComputed());
}

std::string errorOf(const std::string& path) {
  try {
    Ubo2014Btf::read(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

std::vector<char> fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), {});
}
void writeBytes(const std::string& path, const std::vector<char>& b) {
  std::ofstream(path, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
}

TEST(Ubo2014Btf, WrongSignatureNamesTheFile) {
  test::TempDir dir;
  const std::string path = dir / "wrong.btf";
  writeBytes(path, {'h', 'e', 'l', 'l', 'o', '\n'});
  std::string e = errorOf(path);
  EXPECT_EQ(e.rfind(path + ": not a UBO BTF file", 0), 0u) << e;
  EXPECT_NE(e.find("!DFMF08FCR"), std::string::npos) << e;

  const std::string bdi = dir / "bdi.btf";
  std::string text = "!BDIF06R2! and then some";
  writeBytes(bdi, std::vector<char>(text.begin(), text.end()));
  e = errorOf(bdi);
  EXPECT_EQ(e.rfind(bdi + ": signature '!BDIF06R2!' (BDI", 0), 0u) << e;
  EXPECT_NE(e.find("does not read"), std::string::npos) << e;

  EXPECT_NE(errorOf(dir / "missing.btf").find("no such file"), std::string::npos);
}

TEST(Ubo2014Btf, TruncatedFileSaysWhatIsMissing) {
  test::TempDir dir;
  const std::string good = dir / "good.btf";
  smallMaterial(0, 2).write(good);
  std::vector<char> bytes = fileBytes(good);
  const std::string cut = dir / "cut.btf";
  // cuts in the signature, the meta data, the directions, the DFMF fields, and the last channel's SxV
  for (std::size_t keep : {std::size_t{5}, std::size_t{40}, std::size_t{400}, bytes.size() - 200, bytes.size() - 1}) {
    writeBytes(cut, std::vector<char>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(keep)));
    std::string e = errorOf(cut);
    EXPECT_EQ(e.rfind(cut + ": ", 0), 0u) << e;
    if (keep > 10) {
      EXPECT_NE(e.find("truncated while reading"), std::string::npos) << keep << ": " << e;
    }
  }
  writeBytes(cut, std::vector<char>(bytes.begin(), bytes.end() - 1));
  EXPECT_NE(errorOf(cut).find("truncated while reading channel 2's SxV"), std::string::npos) << errorOf(cut);

  std::vector<char> longer = bytes;
  longer.push_back(0);
  writeBytes(cut, longer);
  EXPECT_NE(errorOf(cut).find("1 unexpected bytes after the last channel"), std::string::npos) << errorOf(cut);
}

TEST(Ubo2014Btf, SizesThatDoNotFitAreNamed) {
  test::TempDir dir;
  const std::string good = dir / "good.btf";
  Ubo2014Btf btf = smallMaterial(0, 2);
  btf.write(good);
  std::vector<char> bytes = fileBytes(good);
  // channel 0's header follows the DFMF fields: scalar size (1), components, rows, columns (uint32 each).
  const std::size_t perChannel = 13 + 2 * (2 + 6 * 2 + 12 * 2);
  const std::size_t channel0 = bytes.size() - 3 * perChannel;
  ASSERT_EQ(bytes[channel0], 2);
  std::vector<char> bad = bytes;
  bad[channel0 + 5] = 7;  // rows: 6 -> 7
  writeBytes(dir / "rows.btf", bad);
  std::string e = errorOf(dir / "rows.btf");
  EXPECT_NE(e.find("channel 0: the matrix is 7 x 12, expected 6 (lights x views = 3 x 2) by 12"), std::string::npos) << e;
  bad = bytes;
  bad[channel0] = 3;  // scalar size
  writeBytes(dir / "scalar.btf", bad);
  EXPECT_NE(errorOf(dir / "scalar.btf").find("unknown scalar size 3"), std::string::npos);
  // colour model (int32 after the component count, right after the rotation count)
  bad = bytes;
  const std::size_t model = channel0 - 4 * 9 - 4 * 3 - 4;
  ASSERT_EQ(bad[model], 0);
  bad[model] = 2;  // LAB
  writeBytes(dir / "lab.btf", bad);
  EXPECT_NE(errorOf(dir / "lab.btf").find("colour model LAB is not supported"), std::string::npos) << errorOf(dir / "lab.btf");
}

TEST(Ubo2014Btf, UnknownMetaVersionsAndNonFiniteSingularValuesAreRefused) {
  test::TempDir dir;
  const std::string good = dir / "good.btf";
  smallMaterial(0, 2).write(good);
  const std::vector<char> bytes = fileBytes(good);
  // The meta data version follows the 10-byte signature and the meta data size (uint32).
  const std::size_t version = 10 + 4;
  ASSERT_EQ(bytes[version], 4);
  std::vector<char> bad = bytes;
  bad[version] = 99;
  writeBytes(dir / "v99.btf", bad);
  EXPECT_NE(errorOf(dir / "v99.btf").find("unknown meta data version 99 (nbtf reads versions 1 to 4)"),
            std::string::npos)
      << errorOf(dir / "v99.btf");
  // Channel 0's first singular value (half float after its 13-byte header) as NaN (0x7e00).
  const std::size_t perChannel = 13 + 2 * (2 + 6 * 2 + 12 * 2);
  const std::size_t s0 = bytes.size() - 3 * perChannel + 13;
  bad = bytes;
  bad[s0] = 0x00, bad[s0 + 1] = 0x7e;
  writeBytes(dir / "nan.btf", bad);
  EXPECT_NE(errorOf(dir / "nan.btf").find("channel 0: a singular value is not finite"), std::string::npos)
      << errorOf(dir / "nan.btf");
}

// FMF (read_ubo_fmf.m): one U for all channels (rows channel fastest), one SxV; header version
// 1 adds the dynamic range reduction (exp(x) - eps), version 2 a height map.
TEST(Ubo2014Btf, ReadsFmfAsThreeChannels) {
  test::TempDir dir;
  const std::string dfmf = dir / "d.btf";
  smallMaterial(0, 2).write(dfmf);
  const std::vector<char> bytes = fileBytes(dfmf);
  const std::size_t perChannel = 13 + 2 * (2 + 6 * 2 + 12 * 2);
  const std::size_t headerEnd = bytes.size() - 3 * perChannel - 56;  // signature + common header
  const int k = 2, rows = 18, cols = 12;
  std::vector<float> u(rows * k), sxv(cols * k);
  for (int i = 0; i < rows * k; ++i) u[i] = 0.01f * (i % 23) - 0.05f;
  for (int i = 0; i < cols * k; ++i) sxv[i] = 0.5f + 0.02f * (i % 7);
  auto put = [](std::vector<char>& b, const void* p, std::size_t n) {
    b.insert(b.end(), static_cast<const char*>(p), static_cast<const char*>(p) + n);
  };
  for (std::string sig : {"!FMF06FCR", "!FMF06FC", "!FMF12FCER"}) {
    std::vector<char> b(sig.begin(), sig.end());
    std::size_t end = headerEnd - (sig == "!FMF06FC" ? 4 : 0);  // no rotation count without the 'R'
    b.insert(b.end(), bytes.begin() + 10, bytes.begin() + static_cast<std::ptrdiff_t>(end));
    const bool extended = sig == "!FMF12FCER";
    if (extended) {
      const std::uint8_t version = 2;
      const std::uint32_t drr = 1, hmRows = 2, hmCols = 3;
      put(b, &version, 1), put(b, &drr, 4), put(b, &hmRows, 4), put(b, &hmCols, 4);
      b.insert(b.end(), 2 * 2 * 3, 0);
    }
    const std::uint32_t kk = k, r = rows, c = cols;
    const std::uint8_t scalar = 4;
    put(b, &kk, 4), put(b, &scalar, 1), put(b, &kk, 4), put(b, &r, 4), put(b, &c, 4);
    const float sv[2] = {2, 1};
    put(b, sv, 8), put(b, u.data(), u.size() * 4), put(b, sxv.data(), sxv.size() * 4);
    const std::string path = dir / "f.btf";
    writeBytes(path, b);
    Ubo2014Btf btf = Ubo2014Btf::read(path);
    EXPECT_EQ(btf.meta().signature, sig);
    EXPECT_EQ(btf.meta().colorModel, extended ? 12 : 0);
    EXPECT_EQ(btf.meta().rotations.size(), 0u);
    std::vector<float> abrdf(btf.numImages() * 3);
    btf.abrdfLinear(5, abrdf.data());
    for (int l = 0; l < 3; ++l)
      for (int v = 0; v < 2; ++v)
        for (int ch = 0; ch < 3; ++ch) {
          float want = dot(u, 3 * (l + 3 * v) + ch, sxv, 5, k);
          if (extended) want = std::exp(want) - 1e-5f;
          EXPECT_NEAR(abrdf[(l * 2 + v) * 3 + ch], want, 1e-6f) << sig;
        }
    // written back, it is the equivalent DFMF file
    btf.write(dir / "back.btf");
    EXPECT_EQ(Ubo2014Btf::read(dir / "back.btf").meta().signature, "!DFMF08FCR");
    b.resize(b.size() - 3);
    writeBytes(path, b);
    EXPECT_NE(errorOf(path).find("truncated while reading SxV"), std::string::npos) << errorOf(path);
  }
  const std::string pvf = dir / "p.btf";
  writeBytes(pvf, {'!', 'P', 'V', 'F', '0', '6', 'F', 'C', 'R', 0});
  EXPECT_NE(errorOf(pvf).find("signature '!PVF06FCR' (PVF: per-view factorization) is a UBO BTF format nbtf does not read"),
            std::string::npos)
      << errorOf(pvf);
}

TEST(Ubo2014Btf, LooksLikeUbo2014) {
  test::TempDir dir;
  writeBytes(dir / "a.btf", {'x'});
  writeBytes(dir / "b.bin", {'!', 'D'});
  writeBytes(dir / "c.bin", {'x'});
  EXPECT_TRUE(looksLikeUbo2014(dir / "a.btf"));
  EXPECT_TRUE(looksLikeUbo2014(dir / "b.bin"));
  EXPECT_FALSE(looksLikeUbo2014(dir / "c.bin"));
  EXPECT_FALSE(looksLikeUbo2014(dir.path()));
  EXPECT_EQ(knownUboSignature("!FMF06FCR"), "!FMF06FCR");
  EXPECT_EQ(knownUboSignature("!FMF06FC\x01"), "!FMF06FC");
  EXPECT_EQ(knownUboSignature("!XYZ"), "");
}

}  // namespace
}  // namespace nbtf
