// A terminal progress bar for long stages: "label [#####.....] 52% 3412/6561 12.3 s ETA 11 s".
// Thread-safe advance(); redraws at most ~10 times a second, and only on a terminal
// (a log file gets one line at the end instead of thousands of carriage returns).
#pragma once
#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

namespace nbtf {

class Progress {
 public:
  Progress(std::string label, std::size_t total, bool enabled = true);
  ~Progress();
  void advance(std::size_t count = 1);
  // Extra text shown after the counters (e.g. "loss 0.0123").
  void setStatus(const std::string& status);
  // A stage that ends early (k-means converged) sets its total to what was done, so the
  // last line reads 100% rather than "1% 4/300".
  void setTotal(std::size_t total);
  void finish();
  double elapsedSeconds() const;

  // Globally silence the text bars (tests, --quiet); a listener (setListener) still gets every
  // update.
  static void setQuiet(bool quiet);
  static bool quiet();

  // Progress sent somewhere other than the terminal (the Python module's callback): while a
  // listener is set, every enabled bar calls it instead of drawing, from whichever thread
  // advances it, at most ~10 times a second and once when it finishes (final = true). The
  // listener must not throw. An empty listener restores the terminal.
  struct Update {
    std::string label;
    std::size_t done = 0, total = 0;
    double seconds = 0;
    std::string status;
    bool final = false;
  };
  using Listener = std::function<void(const Update&)>;
  static void setListener(Listener listener);

 private:
  void draw(bool final);
  bool notify(bool final);  // true when a listener took the update
  std::string label_;
  std::atomic<std::size_t> total_;
  std::atomic<std::size_t> done_{0};
  bool enabled_;
  bool finished_ = false;
  bool tty_;
  std::string status_;
  std::mutex mutex_;
  std::chrono::steady_clock::time_point start_, lastDraw_;
};

}  // namespace nbtf
