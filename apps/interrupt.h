// Ctrl-C for the commands that can stop cleanly (compress, decode): the first SIGINT sets a
// flag the work polls, after printing what will happen; SA_RESETHAND restores the default
// action, so a second Ctrl-C ends the process at once.
#pragma once
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

namespace nbtf::cli {

inline std::atomic<bool> gInterruptRequested{false};
inline const char* gInterruptMessage = "";

extern "C" inline void onInterruptSignal(int) {
  gInterruptRequested.store(true);
  ssize_t ignored = ::write(STDERR_FILENO, gInterruptMessage, std::strlen(gInterruptMessage));
  (void)ignored;
}

// `message` (a string literal: it is written from the signal handler) is printed on the first
// Ctrl-C. Returns the flag the work is to poll.
inline std::atomic<bool>* stopOnInterrupt(const char* message) {
  gInterruptMessage = message;
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = onInterruptSignal;
  sa.sa_flags = SA_RESETHAND;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  return &gInterruptRequested;
}

}  // namespace nbtf::cli
