// The `nbtf decode` and `nbtf query` commands end to end: the binary is run on a .nbtf
// file written here; its output stack loads with `nbtf info`, its printed values equal
// the library's, and bad input gives a clear message and a non-zero exit status.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "codec/decoder.h"
#include "codec/decoder_query.h"
#include "decoder_fixtures.h"
#include "io/image_io.h"
#include "io/ubo2014_btf.h"
#include "pipeline/decoder_output.h"
#include "io/btf_names.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {

namespace fs = std::filesystem;

struct CommandRun {
  int status = -1;
  std::string out, err;
};

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Runs `nbtf ARGS` through the shell (ARGS quoted by the caller), capturing both streams.
CommandRun runNbtf(const std::string& args, const test::TempDir& dir, const std::string& stdinText = "") {
  std::string in = dir / "stdin.txt", out = dir / "stdout.txt", err = dir / "stderr.txt";
  writeFileAtomic(in, stdinText);
  std::string cmd = std::string("'") + NBTF_BIN_DIR + "/nbtf' " + args + " <'" + in + "' >'" + out + "' 2>'" + err + "'";
  int raw = std::system(cmd.c_str());
  CommandRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = readText(out);
  r.err = readText(err);
  return r;
}

class NbtfCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    material = testing::makeDisplayableMaterial(4);
    material.layout = Layout::Ubo2003;
    material.sourceSampleType = SampleType::Srgb8;
    file = dir / "m.nbtf";
    writeNbtf(file, material);
  }
  test::TempDir dir;
  CompressedBtf material;
  std::string file;
};

TEST_F(NbtfCommand, DecodeWritesAStackThatInfoLoads) {
  CommandRun r = runNbtf("decode '" + file + "' -o '" + (dir / "out") + "' --threads 2", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("decoded 6 images (3 lights x 2 views), 7 x 5 texels each"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("4 evaluations per image"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir / "out/tv030_pv030/00005 tl015 pl060 tv030 pv030.png"));
  CommandRun info = runNbtf("info '" + (dir / "out") + "' -q", dir);
  ASSERT_EQ(info.status, 0) << info.err;
  EXPECT_NE(info.out.find("layout         ubo2003"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("images         6"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("texels         35"), std::string::npos) << info.out;
}

// One naming per layout: an unmeasured angle in a UBO2003 output gets a UBO2003 name (it
// used to get a UTIA one, mixing both), numbered by its place in the output; the result loads.
TEST_F(NbtfCommand, UnmeasuredAnglesInUbo2003OutputGetUbo2003Names) {
  CommandRun r = runNbtf("decode '" + file + "' -o '" + (dir / "ubo") + "' --lights 0,t37.5p200 --views all -q", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  std::size_t images = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "ubo"))
    if (e.is_regular_file() && e.path().filename() != kDecodeDescriptionName) {
      ++images;
      EXPECT_TRUE(std::isdigit(static_cast<unsigned char>(e.path().filename().string()[0]))) << e.path();
    }
  EXPECT_EQ(images, 4u);
  EXPECT_TRUE(fs::exists(dir / "ubo/tv030_pv030/00003 tl037.500 pl200 tv030 pv030.png")) << r.out;
  CommandRun info = runNbtf("info '" + (dir / "ubo") + "' -q", dir);
  EXPECT_EQ(info.status, 0) << info.err;
}

// Decoding into an earlier decode replaces it whole: a decode in the other layout leaves
// none of the first layout's names behind, so two namings never mix.
TEST_F(NbtfCommand, DecodeReplacesAnEarlierDecodeInTheOtherLayoutWhole) {
  CommandRun r = runNbtf("decode '" + file + "' -o '" + (dir / "out") + "' --layout utia -q", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "out/tv030_pv030/tl015_pl060_tv030_pv030.png"));
  r = runNbtf("decode '" + file + "' -o '" + (dir / "out") + "' -q", dir);  // the source's layout: UBO2003
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "out/tv030_pv030/00005 tl015 pl060 tv030 pv030.png"));
  EXPECT_FALSE(fs::exists(dir / "out/tv030_pv030/tl015_pl060_tv030_pv030.png"));
  CommandRun info = runNbtf("info '" + (dir / "out") + "' -q", dir);
  EXPECT_EQ(info.status, 0) << info.err;
}

TEST_F(NbtfCommand, DecodeOneUnmeasuredPairAtAnotherSize) {
  CommandRun r = runNbtf("decode '" + file + "' -o '" + (dir / "one") +
                      "' --light 37.5,200 --view 10,45 --size 20x9 --format exr --layout utia -q",
                  dir);
  ASSERT_EQ(r.status, 0) << r.err;
  // -q hides progress bars only: the summary is printed, as by every command.
  EXPECT_NE(r.out.find("decoded 1 image"), std::string::npos) << r.out;
  std::string path = dir / "one/tv010_pv045/tl037.500_pl200_tv010_pv045.exr";
  ASSERT_TRUE(fs::exists(path));
  ImageF img = readExr(path);  // XYZ-tagged: read back as linear sRGB
  EXPECT_EQ(img.width, 20);
  EXPECT_EQ(img.height, 9);
  NbtfDecoder dec(material);
  Rgb want = dec.evaluate(3, 2, {37.5, 200}, {10, 45});
  const float* got = &img.rgb[3 * (2 * 20 + 3 + 7)];  // x = 10 wraps to texel 3
  EXPECT_NEAR(got[1], std::max(0.0f, want.g), 2e-3 + 4e-3 * std::fabs(want.g));
}

TEST_F(NbtfCommand, DecodeRejectsBadInput) {
  CommandRun r = runNbtf("decode '" + (dir / "missing.nbtf") + "' -o '" + (dir / "x") + "'", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("nbtf decode: error: " + (dir / "missing.nbtf") + ": cannot open file"), std::string::npos)
      << r.err;
  r = runNbtf("decode '" + file + "' -o '" + (dir / "x") + "' --light 95,0", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--light direction theta = 95 degrees is outside the upper hemisphere"), std::string::npos)
      << r.err;
  r = runNbtf("decode '" + file + "' -o '" + (dir / "x") + "' --lights 0,7", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--lights: item '7' is out of range: the material has 3 light directions (0..2)"),
            std::string::npos)
      << r.err;
  r = runNbtf("decode '" + file + "' -o '" + (dir / "x") + "' --light 10,10 --lights 1", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("give one of them"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x"));
}

// --layout ubo2014: one Bonn .btf file that the loader and `nbtf info` read, holding the
// decoded values (here 6 components: the full rank of 3 x 2 images, so only half precision
// separates them).
TEST_F(NbtfCommand, DecodeUbo2014WritesABtfThatLoadsBack) {
  const std::string out = dir / "m.btf";
  CommandRun r = runNbtf("decode '" + file + "' --layout ubo2014 --components 6 -o '" + out + "' -q", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("wrote " + out + " (ubo2014, !DFMF08FCR, 3 lights x 2 views = 6 images, 7 x 5 texels, 6 "
                                        "components per channel"),
            std::string::npos)
      << r.out;
  Ubo2014Btf btf = Ubo2014Btf::read(out);
  EXPECT_EQ(btf.meta().lights, material.lights);
  EXPECT_EQ(btf.meta().views, material.views);
  EXPECT_EQ(btf.meta().colorModel, 11);
  NbtfDecoder decoder(material);
  BtfStack want = decodeStack(decoder, SampleType::Half, {}, {}, false);
  std::vector<float> abrdf(btf.numImages() * 3);
  double worst = 0, mean = 0;
  for (int t = 0; t < btf.numTexels(); ++t) {
    btf.abrdfLinear(t, abrdf.data());
    for (int i = 0; i < btf.numImages(); ++i)
      for (int c = 0; c < 3; ++c) {
        worst = std::max(worst, static_cast<double>(std::abs(abrdf[i * 3 + c] - want.sample(i, t, c))));
        mean += want.sample(i, t, c) / (3.0 * btf.numImages() * btf.numTexels());
      }
  }
  EXPECT_LT(worst, 5e-3 * mean) << "mean " << mean;
  CommandRun info = runNbtf("info '" + out + "'", dir);
  ASSERT_EQ(info.status, 0) << info.err;
  EXPECT_NE(info.out.find("layout         ubo2014 (signature !DFMF08FCR)"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("components     6, 6, 6 per channel"), std::string::npos) << info.out;

  r = runNbtf("decode '" + file + "' --layout ubo2014 -o '" + (dir / "x.btf") + "' --format exr", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--format does not apply to --layout ubo2014"), std::string::npos) << r.err;
  r = runNbtf("decode '" + file + "' --layout ubo2014 -o '" + dir.path() + "'", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(dir.path() + ": is a folder; --layout ubo2014 writes one .btf file"), std::string::npos) << r.err;
  r = runNbtf("decode '" + file + "' -o '" + (dir / "imgs") + "' --components 4", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--components applies to --layout ubo2014 only"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.btf"));
}

TEST_F(NbtfCommand, QueryPrintsTheLibrarysValue) {
  CommandRun r = runNbtf("query '" + file + "' --texel 5,3 --light 30,60 --view 45,20", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  NbtfDecoder dec(material);
  EXPECT_EQ(r.out, formatRgb(dec.evaluate(5, 3, {30, 60}, {45, 20})) + "\n");
  r = runNbtf("query '" + file + "' --uv 1.5,-0.1 --light 30,60 --view 45,20 --normalized", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, formatRgb(dec.evaluateUv(1.5f, -0.1f, {30, 60}, {45, 20}, OutputScale::Normalized)) + "\n");
}

TEST_F(NbtfCommand, QueryRejectsBadInput) {
  CommandRun r = runNbtf("query '" + file + "' --texel 7,0 --light 30,60 --view 45,20", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("texel (7, 0) is outside the 7 x 5 material"), std::string::npos) << r.err;
  r = runNbtf("query '" + file + "' --texel 1,x --light 30,60 --view 45,20", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--texel: expected X,Y (integers), got '1,x'"), std::string::npos) << r.err;
  r = runNbtf("query '" + file + "' --texel 1,1 --light 30,60", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("needs --light and --view"), std::string::npos) << r.err;
  r = runNbtf("query '" + file + "' --batch '" + dir.path() + "'", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(dir.path() + ": is a folder; --batch reads a CSV file of queries"), std::string::npos) << r.err;
}

TEST_F(NbtfCommand, QueryBatchAnswersTheRestAndFailsAtTheEnd) {
  std::string csv = dir / "q.csv";
  writeFileAtomic(csv, std::string("x,y,theta_l,phi_l,theta_v,phi_v\n1,1,10,20,30,40\n1,1,10\n2,3,45,100,60,200\n"));
  CommandRun r = runNbtf("query '" + file + "' --batch '" + csv + "'", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(csv + ":3: expected 6 comma-separated fields"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("1 malformed line skipped, 2 queries answered"), std::string::npos) << r.err;
  std::istringstream rows(r.out);
  std::string header, a, b, extra;
  std::getline(rows, header), std::getline(rows, a), std::getline(rows, b);
  EXPECT_EQ(header, "x,y,theta_l,phi_l,theta_v,phi_v,r,g,b");
  EXPECT_EQ(a.rfind("1,1,10,20,30,40,", 0), 0u) << a;
  EXPECT_EQ(b.rfind("2,3,45,100,60,200,", 0), 0u) << b;
  EXPECT_FALSE(std::getline(rows, extra));
  // The same from standard input, all well formed: exit 0.
  r = runNbtf("query '" + file + "' --batch - --batch-lines 1", dir, "1,1,10,20,30,40\n2,3,45,100,60,200\n");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find(a), std::string::npos);
  EXPECT_NE(r.out.find(b), std::string::npos);
  r = runNbtf("query '" + file + "' --batch '" + (dir / "none.csv") + "'", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("none.csv: cannot open the query file"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace nbtf
