#include "util/progress.h"
#include "util/timer.h"

#include <unistd.h>

#include <cstdio>

namespace nbtf {
namespace {
std::atomic<bool> g_quiet{false};
std::mutex g_listenerMutex;
std::shared_ptr<const Progress::Listener> g_listener;  // under g_listenerMutex
std::atomic<bool> g_hasListener{false};                 // g_listener is set (checked without the lock)

std::shared_ptr<const Progress::Listener> currentListener() {
  std::lock_guard<std::mutex> lock(g_listenerMutex);
  return g_listener;
}
}  // namespace

void Progress::setQuiet(bool quiet) { g_quiet = quiet; }
bool Progress::quiet() { return g_quiet; }

void Progress::setListener(Listener listener) {
  std::lock_guard<std::mutex> lock(g_listenerMutex);
  g_listener = listener ? std::make_shared<const Listener>(std::move(listener)) : nullptr;
  g_hasListener = g_listener != nullptr;
}

// Called with mutex_ held.
bool Progress::notify(bool final) {
  if (!g_hasListener) return false;
  std::shared_ptr<const Listener> listener = currentListener();
  if (!listener) return false;
  Update u;
  u.label = label_;
  u.done = done_.load();
  u.total = total_.load();
  u.seconds = elapsedSeconds();
  u.status = status_;
  u.final = final;
  (*listener)(u);
  return true;
}

Progress::Progress(std::string label, std::size_t total, bool enabled)
    : label_(std::move(label)),
      total_(total),
      enabled_(enabled && (!g_quiet || g_hasListener)),  // quiet silences the bars, not a listener
      tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      lastDraw_(start_) {}

Progress::~Progress() { finish(); }

double Progress::elapsedSeconds() const {
  return secondsSince(start_);
}

void Progress::advance(std::size_t count) {
  done_ += count;
  if (!enabled_ || (!tty_ && !g_hasListener)) return;
  auto now = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || now - lastDraw_ < std::chrono::milliseconds(100)) return;
  if (notify(false)) {
    lastDraw_ = now;
    return;
  }
  if (!tty_ || g_quiet) return;
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
  if (enabled_ && !notify(true) && !g_quiet) draw(true);
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
