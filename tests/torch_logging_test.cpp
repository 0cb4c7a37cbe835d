// libtorch's glog made quiet (model/autograd/torch_logging.cpp): errors only, to stderr, no log files.
#include "model/autograd/torch_logging.h"

#include <gtest/gtest.h>

#include <string>

#if __has_include(<glog/logging.h>)
#include <glog/logging.h>
#define NBTF_TEST_HAVE_GLOG 1
#endif

namespace nbtf {
namespace {

TEST(TorchLogging, OnlyErrorsReachStderr) {
  detail::quietTorchLogging();
  detail::quietTorchLogging();  // idempotent
#ifdef NBTF_TEST_HAVE_GLOG
  EXPECT_TRUE(google::IsGoogleLoggingInitialized());
  EXPECT_TRUE(FLAGS_logtostderr);  // no log files
  EXPECT_EQ(FLAGS_minloglevel, 2);
  ::testing::internal::CaptureStderr();
  LOG(WARNING) << "nbtf-test-warning";
  LOG(ERROR) << "nbtf-test-error";
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(err.find("nbtf-test-warning"), std::string::npos) << err;
  EXPECT_NE(err.find("nbtf-test-error"), std::string::npos) << err;
#else
  GTEST_SKIP() << "no glog headers: the library does not use glog either";
#endif
}

}  // namespace
}  // namespace nbtf
