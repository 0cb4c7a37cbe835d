// CSV queries: answers equal the API's, malformed lines are reported with their line
// numbers while the rest is still answered, headers/comments/CRLF are accepted.
#include "codec/decoder_query.h"

#include <gtest/gtest.h>

#include <sstream>

#include "decoder_fixtures.h"
#include "test_util.h"

namespace nbtf {
namespace {

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

TEST(DecoderQuery, AnswersWellFormedLinesAndReportsTheOthers) {
  CompressedBtf b = testing::makeDecoderMaterial(4, {37, 21}, 7, 5);
  NbtfDecoder dec(b);
  std::istringstream in(
      "# queries for the test\n"                // 1
      "x,y,theta_l,phi_l,theta_v,phi_v\n"       // 2 header
      "0,0,0,0,0,0\n"                           // 3
      "1, 2 , 30,60,45,20\r\n"                  // 4 spaces and CRLF
      "\n"                                      // 5
      "3,4,37.5,200,10,45,9\n"                  // 6 seven fields
      "3,4,37.5,abc,10,45\n"                    // 7 not a number
      "7,0,10,10,10,10\n"                       // 8 outside the 7 x 5 material
      "2,1,95,0,10,10\n"                        // 9 below the horizon
      "1.5,1,10,10,10,10\n"                     // 10 not an integer
      "6,4,89.5,-30,0,720\n");                  // 11 fine: any finite phi
  std::ostringstream out, err;
  QueryCsvStats s = answerQueryCsv(dec, in, "q.csv", out, err);
  EXPECT_EQ(s.lines, 11u);
  EXPECT_EQ(s.answered, 3u);
  EXPECT_EQ(s.malformed, 5u);

  auto errs = lines(err.str());
  ASSERT_EQ(errs.size(), 5u);
  EXPECT_EQ(errs[0], "q.csv:6: expected 6 comma-separated fields (x,y,theta_l,phi_l,theta_v,phi_v), got 7");
  EXPECT_EQ(errs[1], "q.csv:7: field 4 (phi_l) 'abc' is not a number (degrees)");
  EXPECT_NE(errs[2].find("q.csv:8: texel (7, 0) is outside the 7 x 5 material"), std::string::npos) << errs[2];
  EXPECT_NE(errs[3].find("q.csv:9: light direction theta = 95"), std::string::npos) << errs[3];
  EXPECT_EQ(errs[4], "q.csv:10: field 1 (x) '1.5' is not an integer texel coordinate");

  auto rows = lines(out.str());
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0], "x,y,theta_l,phi_l,theta_v,phi_v,r,g,b");
  struct Expect {
    std::string echo;
    TexelQuery q;
  };
  std::vector<Expect> expect = {{"0,0,0,0,0,0", {0, 0, {0, 0}, {0, 0}}},
                                {"1,2,30,60,45,20", {1, 2, {30, 60}, {45, 20}}},
                                {"6,4,89.5,-30,0,720", {6, 4, {89.5, -30}, {0, 720}}}};
  for (std::size_t i = 0; i < expect.size(); ++i) {
    const std::string& row = rows[i + 1];
    ASSERT_EQ(row.compare(0, expect[i].echo.size() + 1, expect[i].echo + ","), 0) << row;
    float r, g, bl;
    ASSERT_EQ(std::sscanf(row.c_str() + expect[i].echo.size() + 1, "%f,%f,%f", &r, &g, &bl), 3) << row;
    const TexelQuery& q = expect[i].q;
    Rgb want = dec.evaluate(q.x, q.y, q.light, q.view);
    EXPECT_EQ(r, want.r) << row;  // 9 significant digits read back as the same float
    EXPECT_EQ(g, want.g) << row;
    EXPECT_EQ(bl, want.b) << row;
  }
}

TEST(DecoderQuery, StreamingInSmallBatchesGivesTheSameAnswers) {
  NbtfDecoder dec(testing::makeDecoderMaterial(0));
  std::string text;
  for (int i = 0; i < 200; ++i)
    text += std::to_string(i % 7) + "," + std::to_string(i % 5) + "," + std::to_string(i % 90) + "," +
            std::to_string(i * 7) + ",45," + std::to_string(i) + "\n";
  std::string outputs[2];
  for (int k = 0; k < 2; ++k) {
    std::istringstream in(text);
    std::ostringstream out, err;
    QueryCsvOptions o;
    o.batchLines = k == 0 ? 1 : 64;
    QueryCsvStats s = answerQueryCsv(dec, in, "<stdin>", out, err, o);
    EXPECT_EQ(s.answered, 200u);
    EXPECT_TRUE(err.str().empty());
    outputs[k] = out.str();
  }
  EXPECT_EQ(outputs[0], outputs[1]);
}

TEST(DecoderQuery, NormalizedOutputIsNamedSo) {
  CompressedBtf b = testing::makeDecoderMaterial(3);
  NbtfDecoder dec(b);
  std::istringstream in("1,1,10,20,30,40\n");
  std::ostringstream out, err;
  QueryCsvOptions o;
  o.scale = OutputScale::Normalized;
  answerQueryCsv(dec, in, "x", out, err, o);
  auto rows = lines(out.str());
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0], "x,y,theta_l,phi_l,theta_v,phi_v,r_norm,g_norm,b_norm");
  float r;
  ASSERT_EQ(std::sscanf(rows[1].c_str(), "1,1,10,20,30,40,%f", &r), 1);
  EXPECT_EQ(r, dec.evaluate(1, 1, {10, 20}, {30, 40}, OutputScale::Normalized).r);
  EXPECT_EQ(formatRgb({0.5f, 0.25f, 1.0f / 3}), "0.5 0.25 0.333333343");
}

}  // namespace
}  // namespace nbtf
