// The report document model: Markdown tables, HTML escaping and embedding, base64.
#include "eval/report_doc.h"

#include <gtest/gtest.h>

namespace nbtf {
namespace {

std::string b64(const std::string& s) { return base64Encode(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()); }

TEST(ReportDoc, Base64MatchesRfc4648Vectors) {
  EXPECT_EQ(b64(""), "");
  EXPECT_EQ(b64("f"), "Zg==");
  EXPECT_EQ(b64("fo"), "Zm8=");
  EXPECT_EQ(b64("foo"), "Zm9v");
  EXPECT_EQ(b64("foobar"), "Zm9vYmFy");
  const std::uint8_t high[] = {0xFF, 0xFE, 0x00};
  EXPECT_EQ(base64Encode(high, 3), "//4A");
}

Doc sample() {
  Doc d;
  d.title = "T <1>";
  d.heading("Summary").paragraph("RMSE `x` is **0.5** & more");
  d.table({"a", "b|c"}, {{"1", "x|y"}}, "cap", {false, true});
  d.figure("fig.png", "a caption", "alt <text>");
  d.note("careful");
  return d;
}

TEST(ReportDoc, MarkdownHasHeadingsTablesAndFigureLinks) {
  std::string md = renderMarkdown(sample());
  EXPECT_EQ(md.rfind("# T <1>\n", 0), 0u);
  EXPECT_NE(md.find("## Summary\n"), std::string::npos);
  EXPECT_NE(md.find("| a | b\\|c |\n|---|---:|\n| 1 | x\\|y |\n"), std::string::npos);  // pipes escaped, numbers right
  EXPECT_NE(md.find("![alt <text>](fig.png)"), std::string::npos);
  EXPECT_NE(md.find("> careful"), std::string::npos);
}

TEST(ReportDoc, HtmlEscapesTextAndEmbedsFigures) {
  std::map<std::string, std::vector<std::uint8_t>> images{{"fig.png", {'f', 'o', 'o'}}};
  std::string html = renderHtml(sample(), images);
  EXPECT_NE(html.find("<title>T &lt;1&gt;</title>"), std::string::npos);
  EXPECT_NE(html.find("RMSE <code>x</code> is <strong>0.5</strong> &amp; more"), std::string::npos);
  EXPECT_NE(html.find("src=\"data:image/png;base64,Zm9v\""), std::string::npos);
  EXPECT_NE(html.find("alt=\"alt &lt;text&gt;\""), std::string::npos);
  EXPECT_NE(html.find("<td class=\"num\">x|y</td>"), std::string::npos);
  // A figure without bytes falls back to a link by name.
  EXPECT_NE(renderHtml(sample(), {}).find("src=\"fig.png\""), std::string::npos);
}

// A table never widens the page: text cells wrap, and each table scrolls inside a box of the
// page's width (a report's first table, with a long file path, overflowed 1000 px before).
TEST(ReportDoc, TablesWrapTextAndScrollInsideThePage) {
  const std::string html = renderHtml(sample(), {});
  EXPECT_NE(html.find("<div class=\"table\"><table>"), std::string::npos);
  EXPECT_NE(html.find("</table></div>"), std::string::npos);
  EXPECT_NE(html.find("div.table { max-width: 100%; overflow-x: auto; }"), std::string::npos);
  EXPECT_NE(html.find("td { overflow-wrap: anywhere; }"), std::string::npos);
  EXPECT_EQ(html.find("td { white-space: nowrap; }"), std::string::npos);
}

}  // namespace
}  // namespace nbtf
