// A minimal document model for the evaluation report: headings, paragraphs, tables and
// figures, rendered once to Markdown and once to self-contained HTML (figures embedded as
// base64 data URIs), so both say exactly the same thing.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace nbtf {

struct DocBlock {
  enum class Kind { Heading, Paragraph, Table, Figure, Note };
  Kind kind = Kind::Paragraph;
  int level = 2;                                   // Heading
  std::string text;                                // Heading, Paragraph, Note; Figure caption; Table caption
  std::vector<std::string> header;                 // Table
  std::vector<std::vector<std::string>> rows;      // Table
  std::vector<bool> numeric;                       // Table: right-aligned columns
  std::string file;                                // Figure: PNG file name beside the report
  std::string alt;                                 // Figure: alternative text
};

class Doc {
 public:
  std::string title;
  Doc& heading(const std::string& text, int level = 2);
  Doc& paragraph(const std::string& text);
  // A de-emphasized remark (HTML: grey, small).
  Doc& note(const std::string& text);
  Doc& table(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows,
             const std::string& caption = "", const std::vector<bool>& numeric = {});
  Doc& figure(const std::string& file, const std::string& caption, const std::string& alt);
  const std::vector<DocBlock>& blocks() const { return blocks_; }

 private:
  std::vector<DocBlock> blocks_;
};

// Paragraph text may use `code` and **bold** spans (Markdown syntax, converted for HTML).
std::string renderMarkdown(const Doc& doc);
// images: figure file name -> PNG bytes, embedded as data URIs. A figure whose file is
// missing from `images` is linked by name instead.
std::string renderHtml(const Doc& doc, const std::map<std::string, std::vector<std::uint8_t>>& images);

std::string base64Encode(const std::uint8_t* data, std::size_t size);
std::string htmlEscape(const std::string& text);

}  // namespace nbtf
