#include "util/progress.h"

#include <gtest/gtest.h>

namespace nbtf {

// A stage that ends early (k-means converged after 4 of at most 300 iterations) used to end
// its bar at "1% 4/300": with setTotal it ends at 100%.
TEST(Progress, AnEarlyEndShowsFinished) {
  Progress::setQuiet(false);
  ::testing::internal::CaptureStderr();
  {
    Progress bar("k-means", 300, true);
    bar.advance(4);
    bar.setStatus("converged after 4 iterations");
    bar.setTotal(4);
    bar.finish();
  }
  std::string out = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(out.find("100% 4/4"), std::string::npos) << out;
  EXPECT_EQ(out.find("4/300"), std::string::npos) << out;
}

}  // namespace nbtf
