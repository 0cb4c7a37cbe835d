// The CRC-32 of .nbtf headers and sections (codec/crc32.cpp).
#include "codec/crc32.h"

#include <gtest/gtest.h>

namespace nbtf {
namespace {

TEST(Crc32, MatchesTheStandardCheckValue) {
  const char* check = "123456789";
  EXPECT_EQ(crc32(check, 9), 0xCBF43926u);  // the CRC-32/ISO-HDLC check value
  EXPECT_EQ(crc32(crc32(check, 4), check + 4, 5), 0xCBF43926u);
  EXPECT_EQ(crc32("", 0), 0u);
}

}  // namespace
}  // namespace nbtf
