// Every command's every output option against every way it could land on what the command
// reads (util/path_guard.h): inside the input stack folder, inside a linked stack, through a
// link to an input file, into the ground-truth folder, onto the checkpoint or the input file
// itself, behind a `..` of a folder that does not exist. Each is refused before any work: a
// non-zero exit naming the option, the inputs' bytes unchanged and nothing created.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

// Every entry under `root` (links not followed; `recursive` false: its own entries only): its
// type, and a regular file's inode, size and modification time (any write or replacement
// changes them), with `bytes` its contents too.
std::map<std::string, std::string> snapshot(const fs::path& root, bool bytes = false, bool recursive = true) {
  std::map<std::string, std::string> entries;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    if (!recursive) it.disable_recursion_pending();
    const fs::path& p = it->path();
    const std::string key = fs::relative(p, root).string();
    if (it->is_symlink()) entries[key] = "link -> " + fs::read_symlink(p).string();
    else if (it->is_directory()) entries[key] = "folder";
    else {
      struct stat st;
      ::lstat(p.c_str(), &st);
      entries[key] = std::to_string(st.st_ino) + " " + std::to_string(st.st_size) + " " +
                     std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
      if (bytes) {
        const std::vector<std::uint8_t> data = readFileBytes(p.string());
        entries[key] += " " + std::string(data.begin(), data.end());
      }
    }
  }
  return entries;
}

std::string shellQuoted(const std::string& s) { return "'" + s + "'"; }

// One command line with "{}" where the output under test goes, the option that names it, and
// whether that option writes a folder.
struct OutputUse {
  std::string command;  // after "nbtf "
  std::string option;
  bool folder;
};

// The places an output must not go, for a command that reads `stack` or `nbtf`.
struct Target {
  std::string what;
  std::string path;
};

class PathsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = dir_.path();
    stack_ = dir_ / "stack";
    auto synth = test::runProgram("nbtf-synth", "--preset wool --size 8x8 --layout ubo2003 --seed 1 -q -o " + shellQuoted(stack_));
    ASSERT_EQ(synth.exitCode, 0) << synth.output;
    for (const auto& e : fs::recursive_directory_iterator(stack_))
      if (e.path().extension() == ".jpg" && image_.empty()) image_ = e.path().string();
      else if (e.path().extension() == ".exr" && groundTruth_.empty()) groundTruth_ = e.path().string();
    ASSERT_FALSE(image_.empty());
    ASSERT_FALSE(groundTruth_.empty());
    nbtf_ = dir_ / "m.nbtf";
    auto compress = test::runNbtf("compress " + shellQuoted(stack_) + " -o " + shellQuoted(nbtf_) +
                                  " --clusters 3 --epochs 1 --threads 1 -q");
    ASSERT_EQ(compress.exitCode, 0) << compress.output;
    report_ = dir_ / "report";
    auto eval = test::runNbtf("eval " + shellQuoted(nbtf_) + " --reference " + shellQuoted(stack_) + " -o " + shellQuoted(report_) +
                              " --blur-images 0 -q");
    ASSERT_EQ(eval.exitCode, 0) << eval.output;
    fs::create_symlink(stack_, dir_ / "linked");
    fs::create_symlink(image_, dir_ / "image_link.jpg");
    fs::create_symlink(nbtf_, dir_ / "file_link.nbtf");
  }

  // Where a `stack` reader's output may not go: files for a file output, folders for a folder.
  std::vector<Target> stackTargets(bool folder) const {
    const std::string inLink = (fs::path(dir_ / "linked") / fs::relative(image_, stack_)).string();
    if (folder)
      return {{"a new folder inside the stack", stack_ + "/new"},
              {"a folder of the stack", fs::path(image_).parent_path().string()},
              {"a new folder inside the linked stack", dir_ / "linked/new"},
              {"the ground-truth folder", fs::path(groundTruth_).parent_path().string()},
              {"the stack itself", stack_}};
    return {{"an image of the stack", image_},
            {"a new file inside the stack", stack_ + "/new.png"},
            {"an image through a linked stack", inLink},
            {"a link to an image", dir_ / "image_link.jpg"},
            {"the ground truth", groundTruth_},
            {"the stack's synth.json", stack_ + "/synth.json"},
            {"an image behind x/..", dir_ / ("x/../stack/" + fs::relative(image_, stack_).string())}};
  }
  // Where a `.nbtf` reader's output may not go.
  std::vector<Target> fileTargets() const {
    return {{"the .nbtf itself", nbtf_}, {"a link to the .nbtf", dir_ / "file_link.nbtf"},
            {"the .nbtf behind x/..", dir_ / "x/../m.nbtf"}};
  }

  // Runs `use` with `target` as its output: refused, naming the option, nothing changed.
  void expectRefused(const OutputUse& use, const Target& target) {
    SCOPED_TRACE("nbtf " + use.command + " with " + use.option + " = " + target.what + " (" + target.path + ")");
    // Where a write or a new folder would show at once: the scratch folder, the stack, the
    // folder of an image and the target's folder (one level each; the whole tree's bytes are
    // compared once all cases have run).
    const std::string parent = fs::path(target.path).parent_path().lexically_normal().string();
    auto near = [&] {
      std::map<std::string, std::string> all;
      for (const std::string& folder : {root_, stack_, fs::path(image_).parent_path().string(), parent})
        if (fs::is_directory(folder))
          for (const auto& [k, v] : snapshot(folder, false, false)) all[folder + "/" + k] = v;
      return all;
    };
    const auto before = near();
    std::string command = use.command;
    command.replace(command.find("{}"), 2, shellQuoted(target.path));
    const auto r = test::runNbtf(command + " -q");
    EXPECT_NE(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find(use.option), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("nothing was written"), std::string::npos) << r.output;
    EXPECT_TRUE(near() == before) << "the command changed or created files: " << r.output;
  }

  test::TempDir dir_;
  std::string root_, stack_, image_, groundTruth_, nbtf_, report_;
};

TEST_F(PathsTest, EveryOutputOptionOfEveryCommandIsRefusedOnItsInputs) {
  const std::string s = shellQuoted(stack_), f = shellQuoted(nbtf_);
  const std::vector<OutputUse> stackReaders = {
      {"compress " + s + " -o {}", "-o", false},
      {"compress " + s + " -o " + shellQuoted(dir_ / "ok.nbtf") + " --stats-json {}", "--stats-json", false},
      {"compress " + s + " -o " + shellQuoted(dir_ / "ok.nbtf") + " --save-encoder {}", "--save-encoder", false},
      {"cluster " + s + " -k 2 -o {}", "-o", true},
      {"render " + s + " -o {}", "-o", false},
      {"render " + s + " -o " + shellQuoted(dir_ / "ok.png") + " --exr {}", "--exr", false},
      {"render " + s + " -o " + shellQuoted(dir_ / "ok.png") + " --stats-json {}", "--stats-json", false},
      {"render " + s + " -o " + shellQuoted(dir_ / "ok.png") + " --show-refined {}", "--show-refined", false},
      {"render --compare " + s + " " + f + " -o {}", "-o", true},
      {"eval " + f + " --reference " + s + " -o {}", "-o", true},
      {"view " + f + " --reference " + s + " -o {}", "-o", false},
  };
  const auto before = snapshot(root_, true);
  int cases = 0;
  for (const OutputUse& use : stackReaders)
    for (const Target& t : stackTargets(use.folder)) expectRefused(use, t), ++cases;

  const std::vector<OutputUse> fileReaders = {
      {"decode " + f + " -o {}", "-o", true},
      {"decode " + f + " --layout ubo2014 -o {}", "-o", false},
      {"eval " + f + " --reference " + s + " -o {}", "-o", true},
      {"render " + f + " -o {}", "-o", false},
      {"render --compare " + s + " " + f + " -o {}", "-o", true},
      {"view " + f + " -o {}", "-o", false},
      {"export-shader " + f + " -o {}", "-o", true},
  };
  for (const OutputUse& use : fileReaders)
    for (const Target& t : fileTargets()) expectRefused(use, t), ++cases;

  // The summary of a sweep: not into the folder of a report it reads, nor onto the report.
  const std::string reportJson = shellQuoted(report_ + "/report.json");
  for (const Target& t : {Target{"the report's folder", report_}, Target{"the report itself", report_ + "/report.json"}})
    expectRefused({"eval --summarize " + reportJson + " -o {}", "-o", true}, t), ++cases;

  // The checkpoint: another output may not replace it.
  expectRefused({"compress " + s + " -o " + shellQuoted(dir_ / "ok.nbtf") + " --stats-json {}", "--stats-json", false},
                {"the checkpoint", dir_ / "ok.nbtf.ckpt"});
  ++cases;
  EXPECT_GE(cases, 80);
  EXPECT_TRUE(snapshot(root_, true) == before) << "some file's bytes changed";
}

}  // namespace
}  // namespace nbtf
