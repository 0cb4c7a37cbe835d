// Shared test helpers: temporary folders and tiny on-disk stacks in either layout.
#pragma once
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <fstream>

#include "io/btf_names.h"
#include "io/image_io.h"
#include "util/error.h"

namespace nbtf::test {

// A fresh folder under the system temp dir, removed (with everything in it) at scope exit.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "nbtf_test_XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (std::filesystem::path(path_) / name).string(); }

 private:
  std::string path_;
};

// The message of the nbtf::Error `f` throws, or "(no error)".
inline std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// A path in the system temp dir ("nbtf_test_" + name), and `text` written there.
inline std::string tempFilePath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("nbtf_test_" + name)).string();
}
inline std::string writeTempText(const std::string& name, const std::string& text) {
  const std::string path = tempFilePath(name);
  std::ofstream(path) << text;
  return path;
}

// Linear value of texel (x, y), channel c in image (light, view): a smooth, distinct pattern.
inline float patternValue(int light, int view, int x, int y, int c) {
  return 0.05f + 0.9f * static_cast<float>(((light * 7 + view * 3 + x * 5 + y * 11 + c * 13) % 17)) / 16.0f;
}

// Writes a stack with the given directions: UBO2003 (view folders, indexed names) or UTIA.
// Returns the paths written, in (light, view) order.
inline std::vector<std::string> writeTestStack(const std::string& dir, const std::vector<Direction>& lights,
                                               const std::vector<Direction>& views, int w, int h, Layout layout,
                                               ImageFormat format, bool flat = false) {
  std::vector<std::string> paths;
  std::vector<float> rgb(static_cast<std::size_t>(w) * h * 3);
  for (std::size_t l = 0; l < lights.size(); ++l) {
    for (std::size_t v = 0; v < views.size(); ++v) {
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 3; ++c)
            rgb[(static_cast<std::size_t>(y) * w + x) * 3 + c] = patternValue(int(l), int(v), x, y, c);
      std::filesystem::path folder = flat ? std::filesystem::path(dir) : std::filesystem::path(dir) / viewFolderName(views[v]);
      std::filesystem::create_directories(folder);
      std::string name = layout == Layout::Ubo2003
                             ? ubo2003FileName(int(l * views.size() + v), lights[l], views[v], extensionOf(format))
                             : utiaFileName(lights[l], views[v], extensionOf(format));
      std::string path = (folder / name).string();
      if (format == ImageFormat::Exr)
        writeExr(path, w, h, rgb.data(), true,
                 layout == Layout::Utia ? ExrColorSpace::CieXyz : ExrColorSpace::LinearSrgb);
      else
        writeImageSrgb8(path, format, w, h, rgb.data());
      paths.push_back(path);
    }
  }
  return paths;
}

// Asserts that `fn` throws nbtf::Error whose message contains every one of `parts`.
template <class Fn>
void expectErrorContaining(Fn&& fn, const std::vector<std::string>& parts) {
  try {
    fn();
    ADD_FAILURE() << "expected an nbtf::Error";
  } catch (const std::exception& e) {
    std::string msg = e.what();
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "message '" << msg << "' lacks '" << p << "'";
  }
}

// Runs the built `nbtf` with `args` (a shell command line); stdout and stderr together.
struct RunResult {
  int exitCode = -1;
  std::string output;
  double seconds = 0;
};
// Any program of the build's bin/ folder ("nbtf", "nbtf-bench-train", ...).
inline RunResult runProgram(const std::string& program, const std::string& args) {
  const auto start = std::chrono::steady_clock::now();
  std::string cmd = std::string(NBTF_BIN_DIR) + "/" + program + " " + args + " 2>&1";
  RunResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  int status = pclose(p);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}
inline RunResult runNbtf(const std::string& args) { return runProgram("nbtf", args); }

}  // namespace nbtf::test
