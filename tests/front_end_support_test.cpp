// What the library gives front ends beyond the command line (the Python module, python/):
// progress sent to a listener instead of the terminal, and file access errors told apart
// from errors in a file's contents.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

#include "codec/nbtf_file.h"
#include "io/btf_loader.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/progress.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

TEST(ProgressListener, TakesTheUpdatesInsteadOfTheTerminal) {
  Progress::setQuiet(false);
  std::mutex mutex;
  std::vector<Progress::Update> updates;
  Progress::setListener([&](const Progress::Update& u) {
    std::lock_guard<std::mutex> lock(mutex);
    updates.push_back(u);
  });
  ::testing::internal::CaptureStderr();
  {
    Progress bar("stage", 10, true);
    bar.setStatus("half way");
    std::thread other([&] { bar.advance(5); });
    other.join();
    bar.advance(5);
    bar.finish();
    bar.finish();  // once
  }
  Progress bar("silent", 3, /*enabled=*/false);  // a disabled bar says nothing
  bar.advance(3);
  bar.finish();
  Progress::setListener(nullptr);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  ASSERT_FALSE(updates.empty());
  const Progress::Update& last = updates.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.label, "stage");
  EXPECT_EQ(last.done, 10u);
  EXPECT_EQ(last.total, 10u);
  EXPECT_EQ(last.status, "half way");
  int finals = 0;
  for (const auto& u : updates) {
    finals += u.final;
    EXPECT_EQ(u.label, "stage");
  }
  EXPECT_EQ(finals, 1);

  // Without a listener the terminal (here: a log) gets the final line again.
  ::testing::internal::CaptureStderr();
  {
    Progress again("stage", 2, true);
    again.advance(2);
  }
  EXPECT_NE(::testing::internal::GetCapturedStderr().find("100% 2/2"), std::string::npos);
}

std::string scratch(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("nbtf_front_end_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p.string();
}

template <class F>
int accessErrno(F f, std::string& message) {
  try {
    f();
  } catch (const FileAccessError& e) {
    message = e.what();
    return e.errnum();
  } catch (const Error& e) {
    message = e.what();
    return -1;  // a plain Error: the contents, not the access
  }
  return -2;
}

TEST(FileAccessError, NamesWhyAFileCannotBeReached) {
  const std::string missing = scratch("missing");
  std::string message;
  EXPECT_EQ(accessErrno([&] { readFileBytes(missing); }, message), ENOENT);
  EXPECT_EQ(message, missing + ": cannot open file: No such file or directory");
  EXPECT_EQ(accessErrno([&] { readNbtf(missing); }, message), ENOENT);
  EXPECT_EQ(accessErrno([&] { listBtfStack(missing); }, message), ENOENT);
  EXPECT_EQ(message, missing + ": no such file or folder");

  const std::string folder = scratch("folder");
  fs::create_directories(folder);
  EXPECT_EQ(accessErrno([&] { readFileBytes(folder); }, message), EISDIR);
  EXPECT_EQ(message, folder + ": is a folder, expected a file");
  EXPECT_EQ(accessErrno([&] { checkWritable(folder); }, message), EISDIR);
  EXPECT_EQ(accessErrno([&] { checkWritable(folder + "/no/such/x.nbtf"); }, message), ENOENT);

  const std::string file = folder + "/file";
  writeFileAtomic(file, std::string("not a .nbtf file"));
  EXPECT_EQ(accessErrno([&] { listBtfStack(file); }, message), ENOTDIR);
  EXPECT_EQ(accessErrno([&] { createParentFolders(file + "/x/y.nbtf"); }, message), ENOTDIR);
  // A file that is there but wrong is not an access error.
  EXPECT_EQ(accessErrno([&] { readNbtf(file); }, message), -1);
  fs::remove_all(folder);
}

}  // namespace
}  // namespace nbtf
