#include "eval/report_doc.h"

#include <sstream>

namespace nbtf {

Doc& Doc::heading(const std::string& text, int level) {
  DocBlock b;
  b.kind = DocBlock::Kind::Heading, b.text = text, b.level = level;
  blocks_.push_back(b);
  return *this;
}

Doc& Doc::paragraph(const std::string& text) {
  DocBlock b;
  b.kind = DocBlock::Kind::Paragraph, b.text = text;
  blocks_.push_back(b);
  return *this;
}

Doc& Doc::note(const std::string& text) {
  DocBlock b;
  b.kind = DocBlock::Kind::Note, b.text = text;
  blocks_.push_back(b);
  return *this;
}

Doc& Doc::table(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows,
                const std::string& caption, const std::vector<bool>& numeric) {
  DocBlock b;
  b.kind = DocBlock::Kind::Table, b.header = header, b.rows = rows, b.text = caption, b.numeric = numeric;
  b.numeric.resize(header.size(), false);
  blocks_.push_back(b);
  return *this;
}

Doc& Doc::figure(const std::string& file, const std::string& caption, const std::string& alt) {
  DocBlock b;
  b.kind = DocBlock::Kind::Figure, b.file = file, b.text = caption, b.alt = alt;
  blocks_.push_back(b);
  return *this;
}

// ---- Markdown

namespace {
std::string mdCell(const std::string& s) {
  std::string out;
  for (char c : s) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}
}  // namespace

std::string renderMarkdown(const Doc& doc) {
  std::ostringstream md;
  md << "# " << doc.title << "\n\n";
  for (const auto& b : doc.blocks()) {
    switch (b.kind) {
      case DocBlock::Kind::Heading: md << std::string(static_cast<std::size_t>(b.level), '#') << ' ' << b.text << "\n\n"; break;
      case DocBlock::Kind::Paragraph: md << b.text << "\n\n"; break;
      case DocBlock::Kind::Note: md << "> " << b.text << "\n\n"; break;
      case DocBlock::Kind::Figure:
        md << "![" << b.alt << "](" << b.file << ")\n\n*" << b.text << "*\n\n";
        break;
      case DocBlock::Kind::Table: {
        if (!b.text.empty()) md << "*" << b.text << "*\n\n";
        md << '|';
        for (const auto& h : b.header) md << ' ' << mdCell(h) << " |";
        md << "\n|";
        for (std::size_t c = 0; c < b.header.size(); ++c) md << (b.numeric[c] ? "---:|" : "---|");
        md << '\n';
        for (const auto& row : b.rows) {
          md << '|';
          for (const auto& cell : row) md << ' ' << mdCell(cell) << " |";
          md << '\n';
        }
        md << '\n';
        break;
      }
    }
  }
  return md.str();
}

// ---- HTML

std::string htmlEscape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

namespace {
// Escapes, then turns `code` and **bold** spans into tags.
std::string inlineHtml(const std::string& text) {
  std::string s = htmlEscape(text), out;
  bool code = false, bold = false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '`') {
      out += code ? "</code>" : "<code>";
      code = !code;
    } else if (!code && s.compare(i, 2, "**") == 0) {
      out += bold ? "</strong>" : "<strong>";
      bold = !bold;
      ++i;
    } else {
      out += s[i];
    }
  }
  if (code) out += "</code>";
  if (bold) out += "</strong>";
  return out;
}

const char* kStyle = R"(
body { font-family: -apple-system, "Segoe UI", "DejaVu Sans", Helvetica, Arial, sans-serif; color: #1d1d1f;
       max-width: 1080px; margin: 24px auto; padding: 0 24px; line-height: 1.45; font-size: 15px; }
h1 { font-size: 26px; border-bottom: 2px solid #2a6f97; padding-bottom: 6px; }
h2 { font-size: 20px; margin-top: 34px; border-bottom: 1px solid #d0d7de; padding-bottom: 4px; color: #1f4e6b; }
h3 { font-size: 16px; margin-top: 22px; }
table { border-collapse: collapse; margin: 8px 0 18px; font-size: 14px; }
th, td { border: 1px solid #d0d7de; padding: 4px 10px; }
th { background: #eef3f7; text-align: left; }
td { overflow-wrap: anywhere; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
div.table { max-width: 100%; overflow-x: auto; }
tr:nth-child(even) td { background: #fafbfc; }
p.caption { font-style: italic; color: #444; margin: 14px 0 2px; font-size: 14px; }
figure { margin: 12px 0 22px; }
figure img { max-width: 100%; border: 1px solid #e1e4e8; }
figcaption { color: #444; font-size: 13px; margin-top: 4px; max-width: 900px; }
p.note { color: #555; font-size: 13px; border-left: 3px solid #d0d7de; padding-left: 10px; }
code { background: #f3f4f6; padding: 1px 4px; border-radius: 3px; font-size: 13px; }
)";
}  // namespace

std::string base64Encode(const std::uint8_t* data, std::size_t size) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  for (std::size_t i = 0; i < size; i += 3) {
    std::uint32_t v = static_cast<std::uint32_t>(data[i]) << 16;
    if (i + 1 < size) v |= static_cast<std::uint32_t>(data[i + 1]) << 8;
    if (i + 2 < size) v |= data[i + 2];
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < size ? kAlphabet[(v >> 6) & 63] : '=';
    out += i + 2 < size ? kAlphabet[v & 63] : '=';
  }
  return out;
}

std::string renderHtml(const Doc& doc, const std::map<std::string, std::vector<std::uint8_t>>& images) {
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" << htmlEscape(doc.title)
    << "</title>\n<style>" << kStyle << "</style>\n</head>\n<body>\n<h1>" << inlineHtml(doc.title) << "</h1>\n";
  for (const auto& b : doc.blocks()) {
    switch (b.kind) {
      case DocBlock::Kind::Heading: h << "<h" << b.level << '>' << inlineHtml(b.text) << "</h" << b.level << ">\n"; break;
      case DocBlock::Kind::Paragraph: h << "<p>" << inlineHtml(b.text) << "</p>\n"; break;
      case DocBlock::Kind::Note: h << "<p class=\"note\">" << inlineHtml(b.text) << "</p>\n"; break;
      case DocBlock::Kind::Figure: {
        auto it = images.find(b.file);
        std::string src = it == images.end() ? htmlEscape(b.file)
                                             : "data:image/png;base64," + base64Encode(it->second.data(), it->second.size());
        h << "<figure><img src=\"" << src << "\" alt=\"" << htmlEscape(b.alt) << "\"><figcaption>" << inlineHtml(b.text)
          << "</figcaption></figure>\n";
        break;
      }
      case DocBlock::Kind::Table: {
        if (!b.text.empty()) h << "<p class=\"caption\">" << inlineHtml(b.text) << "</p>\n";
        // Text cells wrap (a long path or note no longer widens the page); a table of many
        // numeric columns scrolls inside its box instead of overflowing it.
        h << "<div class=\"table\"><table>";
        h << "<thead><tr>";
        for (const auto& c : b.header) h << "<th>" << inlineHtml(c) << "</th>";
        h << "</tr></thead><tbody>\n";
        for (const auto& row : b.rows) {
          h << "<tr>";
          for (std::size_t c = 0; c < row.size(); ++c)
            h << (c < b.numeric.size() && b.numeric[c] ? "<td class=\"num\">" : "<td>") << inlineHtml(row[c]) << "</td>";
          h << "</tr>\n";
        }
        h << "</tbody></table></div>\n";
        break;
      }
    }
  }
  h << "</body>\n</html>\n";
  return h.str();
}

}  // namespace nbtf
