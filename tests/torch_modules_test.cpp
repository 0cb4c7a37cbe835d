// The encoder and decoder modules' shapes (model/autograd/torch_modules.cpp): encoder blocks and widths per image count.
#include <gtest/gtest.h>

#include <vector>

#include "model/config/train_config.h"

namespace nbtf {

TEST(Trainer, EncoderBlocksAdaptToImageCount) {
  EXPECT_EQ(encoderBlockCount(6561, 3), 3);  // 6561 -> 2187 -> 729 -> 243
  EXPECT_EQ(encoderBlockCount(6561, 5), 5);  // -> 81 -> 27
  EXPECT_EQ(encoderBlockCount(22801, 4), 4);
  EXPECT_EQ(encoderBlockCount(81, 3), 3);    // 81 -> 27 -> 9 -> 3
  EXPECT_EQ(encoderBlockCount(9, 3), 1);     // 9 -> 3, one more would leave 1
  EXPECT_EQ(encoderBlockCount(4, 3), 0);     // too short to pool: linear map only
  // UBO2014's 22,801 images: one more block than configured, as the paper's predecessor had
  EXPECT_EQ(encoderWidths(22801, {4, 8, 16}), (std::vector<int>{4, 8, 16, 32}));  // -> 844 -> 281
  EXPECT_EQ(encoderWidths(6561, {4, 8, 16}), (std::vector<int>{4, 8, 16}));       // unchanged
  EXPECT_EQ(encoderWidths(6561, {4, 8}), (std::vector<int>{4, 8}));               // 81 x 81: as configured
  EXPECT_EQ(encoderWidths(81, {4, 8, 16}), (std::vector<int>{4, 8, 16}));
  EXPECT_EQ(encoderWidths(9, {4, 8, 16}), (std::vector<int>{4}));
  EXPECT_EQ(encoderWidths(22801, {4, 8}), (std::vector<int>{4, 8, 16, 32}));      // 2533 -> 844 -> 281
}

}  // namespace nbtf
