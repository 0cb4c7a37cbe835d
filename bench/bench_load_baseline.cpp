// The baseline of scripts/bench_load.sh: a plain sequential cv::imread loop over every
// image of a stack, copying the crop out of each, as a user would write it by hand.
// Usage: bench_load_baseline <stack-dir> X,Y,W,H
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s <stack-dir> X,Y,W,H\n", argv[0]);
    return 2;
  }
  int x, y, w, h;
  if (std::sscanf(argv[2], "%d,%d,%d,%d", &x, &y, &w, &h) != 4) return 2;
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(argv[1])) {
    std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".jpg" || ext == ".png") &&
        e.path().parent_path().filename().string().rfind("tv", 0) == 0)
      files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  auto start = std::chrono::steady_clock::now();
  std::vector<unsigned char> data(files.size() * std::size_t(w) * h * 3);
  for (std::size_t i = 0; i < files.size(); ++i) {
    cv::Mat m = cv::imread(files[i], cv::IMREAD_COLOR);
    if (m.empty()) {
      std::fprintf(stderr, "cannot read %s\n", files[i].c_str());
      return 1;
    }
    for (int r = 0; r < h; ++r)
      std::copy_n(m.ptr<unsigned char>(y + r) + 3 * x, 3 * w, data.data() + (i * h + r) * std::size_t(w) * 3);
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("images %zu seconds %.3f\n", files.size(), seconds);
  return 0;
}
