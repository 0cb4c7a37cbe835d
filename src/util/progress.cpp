#include "util/progress.h"
#include "util/timer.h"

#include <unistd.h>

#include <cstdio>

namespace nbtf {
namespace {
std::atomic<bool> g_quiet{false};
}

void Progress::setQuiet(bool quiet) { g_quiet = quiet; }
bool Progress::quiet() { return g_quiet; }

Progress::Progress(std::string label, std::size_t total, bool enabled)
    : label_(std::move(label)),
      total_(total),
      enabled_(enabled && !g_quiet),
      tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      lastDraw_(start_) {}

Progress::~Progress() { finish(); }

double Progress::elapsedSeconds() const {
  return secondsSince(start_);
}

void Progress::advance(std::size_t count) {
  done_ += count;
  if (!enabled_ || !tty_) return;
  auto now = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || now - lastDraw_ < std::chrono::milliseconds(100)) return;
  lastDraw_ = now;
  draw(false);
}

void Progress::setStatus(const std::string& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  status_ = status;
}

void Progress::setTotal(std::size_t total) { total_ = total; }

void Progress::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (enabled_) draw(true);
}

void Progress::draw(bool final) {
  std::size_t done = done_.load(), total = total_.load();
  double fraction = total ? static_cast<double>(done) / total : 1.0;
  if (fraction > 1) fraction = 1;
  double elapsed = elapsedSeconds();
  const int width = 30;
  int filled = static_cast<int>(fraction * width);
  std::string bar(filled, '#');
  bar.append(width - filled, '.');
  char eta[64] = "";
  if (!final && done > 0 && fraction < 1) {
    std::snprintf(eta, sizeof eta, " ETA %.0f s", elapsed / fraction - elapsed);
  }
  std::fprintf(stderr, "%s%s [%s] %3.0f%% %zu/%zu %.1f s%s%s%s%s", tty_ ? "\r" : "", label_.c_str(),
               bar.c_str(), fraction * 100, done, total, elapsed, eta, status_.empty() ? "" : "  ",
               status_.c_str(), tty_ ? "\033[K" : "");
  if (final) std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace nbtf
