// The documentation's relative links (README.md and docs/**/*.md): every file or folder a
// link or image names exists, so a moved section or figure cannot leave a dead link behind.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace nbtf {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> markdownFiles() {
  const fs::path root(NBTF_SOURCE_DIR);
  std::vector<fs::path> files{root / "README.md"};
  for (const auto& entry : fs::recursive_directory_iterator(root / "docs"))
    if (entry.is_regular_file() && entry.path().extension() == ".md") files.push_back(entry.path());
  return files;
}

// The targets of the file's Markdown links and images, outside code spans and fenced blocks:
// relative paths only (no scheme, no in-page anchor), without their #fragment.
std::vector<std::pair<int, std::string>> relativeLinks(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::pair<int, std::string>> links;
  static const std::regex link(R"(\]\(([^)\s]+)\))");
  static const std::regex codeSpan("`[^`]*`");
  std::string line;
  bool fenced = false;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.rfind("```", 0) == 0) fenced = !fenced;
    if (fenced) continue;
    const std::string text = std::regex_replace(line, codeSpan, "");
    for (std::sregex_iterator m(text.begin(), text.end(), link), end; m != end; ++m) {
      std::string target = (*m)[1].str();
      if (target.find("://") != std::string::npos || target.rfind("mailto:", 0) == 0 || target[0] == '#') continue;
      target = target.substr(0, target.find('#'));
      if (!target.empty()) links.emplace_back(number, target);
    }
  }
  return links;
}

TEST(DocLinks, EveryRelativeLinkNamesAnExistingFile) {
  const std::vector<fs::path> files = markdownFiles();
  ASSERT_GE(files.size(), 10u) << "README.md and docs/*.md";
  int checked = 0;
  for (const fs::path& file : files)
    for (const auto& [line, target] : relativeLinks(file)) {
      ++checked;
      EXPECT_TRUE(fs::exists(file.parent_path() / target)) << file.string() << ":" << line << ": '" << target
                                                          << "' does not exist";
    }
  EXPECT_GE(checked, 50) << "links found in the documentation";
}

}  // namespace
}  // namespace nbtf
