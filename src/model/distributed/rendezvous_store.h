// The rendezvous of a data-parallel run: a small key-value store over TCP. Rank 0 hosts it at
// the --master address, bound to that address only (libtorch's TCPStore listens on every
// interface and cannot be bound to one), and every rank, rank 0 too, reaches it as a client.
// Every connection first presents the run's shared secret (--dist-secret / NBTF_DIST_SECRET);
// a peer without it is refused before it can read or write a key. distributed.cpp adapts the
// client to c10d::Store for Gloo. PRIVATE to src/model (and its tests); torch-free.
#pragma once
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace nbtf::detail {

using StoreBytes = std::vector<std::uint8_t>;
using StoreClock = std::chrono::steady_clock;

class RendezvousServer {
 public:
  // Binds HOST:PORT (HOST as getaddrinfo resolves it; the first address this machine has) and
  // serves in a thread until destroyed. Throws nbtf::Error at once when the port is in use
  // ("port N on HOST is already in use") or HOST is not an address of this machine.
  RendezvousServer(const std::string& host, int port, const std::string& secret);
  ~RendezvousServer();
  RendezvousServer(const RendezvousServer&) = delete;
  RendezvousServer& operator=(const RendezvousServer&) = delete;
  // The bound address, "127.0.0.1:29500" ("[::1]:29500" for IPv6).
  const std::string& address() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class RendezvousClient {
 public:
  // Connects to HOST:PORT, retrying until `deadline` (rank 0 may start later), and presents
  // `secret`. Throws nbtf::Error when rank 0 cannot be reached by then, or when it refuses the
  // secret (the error names --dist-secret and NBTF_DIST_SECRET).
  RendezvousClient(const std::string& host, int port, const std::string& secret, StoreClock::time_point deadline);
  ~RendezvousClient();
  RendezvousClient(const RendezvousClient&) = delete;
  RendezvousClient& operator=(const RendezvousClient&) = delete;

  void set(const std::string& key, const StoreBytes& value);
  std::optional<StoreBytes> tryGet(const std::string& key);
  // Waits (polling) until the key exists; throws nbtf::Error naming the key at `deadline`.
  StoreBytes get(const std::string& key, StoreClock::time_point deadline);
  // c10d semantics: the key holds a decimal integer (absent = 0); returns the new value.
  std::int64_t add(const std::string& key, std::int64_t delta);
  // c10d semantics: set to `desired` when the current value is `expected` (absent counts as
  // empty), and return the value after the call (`expected` when absent and not empty).
  StoreBytes compareSet(const std::string& key, const StoreBytes& expected, const StoreBytes& desired);
  bool check(const std::vector<std::string>& keys);
  bool deleteKey(const std::string& key);
  std::int64_t numKeys();
  // Waits until every key exists; throws nbtf::Error naming the missing keys at `deadline`.
  void wait(const std::vector<std::string>& keys, StoreClock::time_point deadline);

 private:
  StoreBytes request(const StoreBytes& body);
  int fd_ = -1;
  std::string where_;  // "rank 0's rendezvous at HOST:PORT", for errors
  std::mutex mutex_;   // one request at a time on the connection
};

// True when `given` equals `secret`, in time that depends on given's length only.
bool sameSecret(const std::string& given, const std::string& secret);
// A random secret for one run: 32 hex digits from the system's random source.
std::string randomSecret();

}  // namespace nbtf::detail
