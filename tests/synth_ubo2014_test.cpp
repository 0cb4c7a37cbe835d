// nbtf-synth --layout ubo2014: the synthetic material under Bonn's 151 x 151 Dome 1 directions,
// written as a UBO2014 .btf file that the loader reads back close to the render.
#include "synth/synth_ubo2014.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "io/btf_loader.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf::synth {
namespace {

TEST(SynthUbo2014, WritesDome1MaterialTheLoaderReads) {
  test::TempDir dir;
  SynthOptions o;
  o.preset = "fabric";
  o.width = 8, o.height = 8;
  o.render.supersampling = 1;
  o.progress = false;
  Ubo2014FactorizeOptions f;
  f.components = 64;  // the full rank of 8 x 8 texels
  f.colorModel = 0;
  const std::string path = dir / "fabric.btf";
  SynthUbo2014Summary s = writeSynthUbo2014(o, path, f);
  EXPECT_EQ(s.images, 22801);
  EXPECT_EQ(s.factorization.components, 64);
  EXPECT_EQ(s.fileBytes, std::filesystem::file_size(path));
  // full rank: only half precision separates the stored factors from the render
  EXPECT_LT(s.factorization.rmseLinear, 2e-3 * s.factorization.inputMean);

  Ubo2014Btf btf = Ubo2014Btf::read(path);
  EXPECT_EQ(btf.meta().lights, dome151());
  EXPECT_EQ(btf.meta().views, dome151());
  EXPECT_NE(btf.meta().xml.find("preset=\"fabric\""), std::string::npos) << btf.meta().xml;

  // The loaded stack against the renderer for a few pairs.
  LoadOptions load;
  load.progress = false;
  BtfStack stack = loadBtfStack(path, load);
  SynthMaterial material(o.preset, o.width, o.height, o.seed, o.render);
  std::vector<float> want(8 * 8 * 3);
  for (int image : {0, 151 * 37 + 100, 22800}) {
    material.render(dome151()[image / 151], dome151()[image % 151], want.data());
    double sum = 0, err = 0;
    for (int t = 0; t < 64; ++t)
      for (int c = 0; c < 3; ++c) {
        sum += want[t * 3 + c];
        err += std::abs(stack.sample(image, t, c) - want[t * 3 + c]);
      }
    EXPECT_LT(err, 5e-3 * sum + 1e-4) << "image " << image;
  }
}

TEST(SynthUbo2014, RefusesAFolderAndImageOptions) {
  test::TempDir dir;
  SynthOptions o;
  o.width = 8, o.height = 8;
  o.progress = false;
  EXPECT_THROW(writeSynthUbo2014(o, dir.path(), {}), Error);
  std::string cmd = std::string("'") + NBTF_BIN_DIR + "/nbtf-synth' --layout ubo2014 --format png -o '" +
                    (dir / "x.btf") + "' >/dev/null 2>&1";
  int raw = std::system(cmd.c_str());
  EXPECT_EQ(WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, 1);
  for (const char* only : {"--components 4", "--memory-limit 1G", "--power-iterations 1"}) {
    cmd = std::string("'") + NBTF_BIN_DIR + "/nbtf-synth' --layout ubo2003 " + only + " -o '" + (dir / "y") +
          "' >/dev/null 2>&1";
    raw = std::system(cmd.c_str());
    EXPECT_EQ(WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, 1) << only;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "x.btf"));
}

}  // namespace
}  // namespace nbtf::synth
