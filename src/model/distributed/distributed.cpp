#include "model/distributed/distributed.h"

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>
#include <arpa/inet.h>
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <torch/csrc/distributed/c10d/Store.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>

#include "model/distributed/distributed_group.h"
#include "model/autograd/torch_logging.h"
#include "model/distributed/rendezvous_store.h"
#include "util/error.h"
#include "util/timer.h"

namespace nbtf {

namespace {
// "HOST:PORT" -> host, port; throws naming --master.
void splitMaster(const std::string& master, std::string& host, int& port) {
  const auto colon = master.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == master.size())
    throw Error("--master: expected HOST:PORT (e.g. 127.0.0.1:29500), got '" + master + "'");
  host = master.substr(0, colon);
  try {
    std::size_t used = 0;
    port = std::stoi(master.substr(colon + 1), &used);
    if (used != master.size() - colon - 1) throw std::invalid_argument("trailing");
  } catch (const std::exception&) {
    throw Error("--master: the port of '" + master + "' is not a number");
  }
  if (port < 1 || port > 65535) throw Error("--master: port " + std::to_string(port) + " is outside 1..65535");
}
}  // namespace

void validateDistributedConfig(const DistributedConfig& c) {
  if (c.worldSize < 1) throw Error("--world-size must be >= 1, got " + std::to_string(c.worldSize));
  if (c.rank < 0 || c.rank >= c.worldSize)
    throw Error("--rank " + std::to_string(c.rank) + " must be in 0.." + std::to_string(c.worldSize - 1) +
                " (--world-size " + std::to_string(c.worldSize) + ")");
  if (!(c.timeoutSeconds > 0) || !std::isfinite(c.timeoutSeconds))
    throw Error("--dist-timeout must be a positive number of seconds");
  if (c.enabled()) {
    std::string host;
    int port = 0;
    splitMaster(c.master, host, port);
  }
}

void completeDistributedSecret(DistributedConfig& c) {
  if (!c.enabled() || !c.secret.empty()) return;
  if (const char* env = std::getenv("NBTF_DIST_SECRET"); env && *env) {
    c.secret = env;
    return;
  }
  if (c.rank != 0)
    throw Error("--rank " + std::to_string(c.rank) +
                ": the rendezvous needs rank 0's shared secret: pass --dist-secret SECRET or set NBTF_DIST_SECRET "
                "(rank 0 prints the one it generates when it is given none)");
  c.secret = detail::randomSecret();
  std::fprintf(stderr,
               "nbtf: no --dist-secret or NBTF_DIST_SECRET given; this run's rendezvous secret is %s: start the other "
               "ranks with NBTF_DIST_SECRET=%s in their environment (or --dist-secret %s)\n",
               c.secret.c_str(), c.secret.c_str(), c.secret.c_str());
}

namespace {
std::string shown(const std::string& value) {
  return value.size() <= 80 ? value : value.substr(0, 77) + "...";
}
}  // namespace

std::string distributedMismatch(const std::vector<std::pair<std::string, std::string>>& reference,
                                const std::vector<std::pair<std::string, std::string>>& mine, int rank) {
  const std::string r = std::to_string(rank);
  auto find = [](const std::vector<std::pair<std::string, std::string>>& list, const std::string& name) {
    for (const auto& entry : list)
      if (entry.first == name) return &entry.second;
    return static_cast<const std::string*>(nullptr);
  };
  for (const auto& [name, value] : reference) {
    const std::string* other = find(mine, name);
    if (!other) return name + ": rank 0 checks it, rank " + r + " does not (another nbtf version?)";
    if (*other != value) return name + " differs: rank 0 has " + shown(value) + ", rank " + r + " has " + shown(*other);
  }
  for (const auto& entry : mine)
    if (!find(reference, entry.first))
      return entry.first + ": rank " + r + " checks it, rank 0 does not (another nbtf version?)";
  return "";
}

void tileShare(int tiles, int rank, int worldSize, int& begin, int& end) {
  const int base = tiles / worldSize, extra = tiles % worldSize;
  begin = rank * base + std::min(rank, extra);
  end = begin + base + (rank < extra ? 1 : 0);
}

namespace detail {

namespace {

// An exception's message on one line (userMessage, without libtorch's backtrace).
std::string oneLine(const std::exception& e) {
  std::string s = userMessage(e);
  for (char& ch : s)
    if (ch == '\n') ch = ' ';
  return s;
}

// The address of this machine's interface that reaches `host` (a UDP socket "connected" to
// it sends nothing; the kernel just picks the route): Gloo's transport binds there.
std::string localAddressTowards(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* list = nullptr;
  if (getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &list) != 0 || !list)
    throw Error("--master: cannot resolve host '" + host + "'");
  std::string found;
  for (addrinfo* a = list; a && found.empty(); a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype, a->ai_protocol);
    if (fd < 0) continue;
    sockaddr_storage local{};
    socklen_t len = sizeof local;
    if (::connect(fd, a->ai_addr, a->ai_addrlen) == 0 &&
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &len) == 0) {
      char text[INET6_ADDRSTRLEN] = "";
      const void* addr = local.ss_family == AF_INET
                             ? static_cast<const void*>(&reinterpret_cast<sockaddr_in*>(&local)->sin_addr)
                             : static_cast<const void*>(&reinterpret_cast<sockaddr_in6*>(&local)->sin6_addr);
      if (inet_ntop(local.ss_family, addr, text, sizeof text)) found = text;
    }
    ::close(fd);
  }
  freeaddrinfo(list);
  if (found.empty()) throw Error("--master: no interface of this machine reaches " + host);
  return found;
}

StoreBytes encodeList(const std::vector<std::pair<std::string, std::string>>& list) {
  StoreBytes out;
  auto put = [&](const std::string& s) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(s.size() >> (8 * i)));
    out.insert(out.end(), s.begin(), s.end());
  };
  for (const auto& [name, value] : list) put(name), put(value);
  return out;
}

std::vector<std::pair<std::string, std::string>> decodeList(const StoreBytes& b) {
  std::vector<std::pair<std::string, std::string>> list;
  std::size_t at = 0;
  auto take = [&](std::string& s) {
    if (b.size() - at < 4) throw Error("rank 0 sent a malformed list of settings");
    std::size_t n = 0;
    for (int i = 0; i < 4; ++i) n |= static_cast<std::size_t>(b[at + i]) << (8 * i);
    at += 4;
    if (b.size() - at < n) throw Error("rank 0 sent a malformed list of settings");
    s.assign(b.begin() + static_cast<std::ptrdiff_t>(at), b.begin() + static_cast<std::ptrdiff_t>(at + n));
    at += n;
  };
  while (at < b.size()) {
    std::pair<std::string, std::string> entry;
    take(entry.first);
    take(entry.second);
    list.push_back(std::move(entry));
  }
  return list;
}

StoreBytes bytesOf(const std::string& s) { return StoreBytes(s.begin(), s.end()); }
std::string textOf(const StoreBytes& b) { return std::string(b.begin(), b.end()); }

// c10d's view of the rendezvous (what ProcessGroupGloo exchanges its addresses through).
// Blocking operations poll; while `limit` is set, no wait goes past it, so the whole
// rendezvous keeps one deadline.
class RendezvousStore : public c10d::Store {
 public:
  RendezvousStore(std::unique_ptr<RendezvousClient> client, std::chrono::milliseconds timeout)
      : c10d::Store(timeout), client_(std::move(client)) {}
  RendezvousClient& client() { return *client_; }
  void limit(std::optional<StoreClock::time_point> deadline) { limit_ = deadline; }

  void set(const std::string& key, const std::vector<uint8_t>& value) override { client_->set(key, value); }
  std::vector<uint8_t> compareSet(const std::string& key, const std::vector<uint8_t>& expected,
                                  const std::vector<uint8_t>& desired) override {
    return client_->compareSet(key, expected, desired);
  }
  std::vector<uint8_t> get(const std::string& key) override { return client_->get(key, deadlineAfter(timeout_)); }
  int64_t add(const std::string& key, int64_t value) override { return client_->add(key, value); }
  bool deleteKey(const std::string& key) override { return client_->deleteKey(key); }
  bool check(const std::vector<std::string>& keys) override { return client_->check(keys); }
  int64_t getNumKeys() override { return client_->numKeys(); }
  void wait(const std::vector<std::string>& keys) override { client_->wait(keys, deadlineAfter(timeout_)); }
  void wait(const std::vector<std::string>& keys, const std::chrono::milliseconds& timeout) override {
    client_->wait(keys, deadlineAfter(timeout));
  }

 private:
  StoreClock::time_point deadlineAfter(std::chrono::milliseconds timeout) const {
    // kNoTimeout (0) waits without end; a year stands for that.
    StoreClock::time_point d =
        StoreClock::now() + (timeout == kNoTimeout ? std::chrono::hours(24 * 365) : StoreClock::duration(timeout));
    if (limit_ && *limit_ < d) d = *limit_;
    return d;
  }
  std::unique_ptr<RendezvousClient> client_;
  std::optional<StoreClock::time_point> limit_;
};

}  // namespace

struct DistributedGroup::State {
  std::unique_ptr<RendezvousServer> server;  // rank 0 only; declared first, so destroyed last
  c10::intrusive_ptr<RendezvousStore> store;
  c10::intrusive_ptr<c10d::ProcessGroupGloo> group;
  std::chrono::milliseconds timeout{0};
};

DistributedGroup::DistributedGroup(const DistributedConfig& config) : config_(config), state_(new State) {
  quietTorchLogging();
  validateDistributedConfig(config_);
  completeDistributedSecret(config_);
  std::string host;
  int port = 0;
  splitMaster(config_.master, host, port);
  state_->timeout = std::chrono::milliseconds(static_cast<long long>(config_.timeoutSeconds * 1000));
  // One deadline for the whole rendezvous: connecting, the settings check and Gloo's mesh.
  const StoreClock::time_point deadline = StoreClock::now() + state_->timeout;
  const int rank = config_.rank, world = config_.worldSize;
  const std::string who = "distributed training (rank " + std::to_string(rank) + " of " + std::to_string(world) +
                          ", master " + config_.master + ")";
  const std::string within = std::to_string(static_cast<int>(std::lround(config_.timeoutSeconds))) + " s";
  const std::string hint = "start every rank with the same --master, --world-size and --dist-secret";
  try {
    if (rank == 0) state_->server = std::make_unique<RendezvousServer>(host, port, config_.secret);
    state_->store = c10::make_intrusive<RendezvousStore>(
        std::make_unique<RendezvousClient>(host, port, config_.secret, deadline), state_->timeout);
  } catch (const std::exception& e) {
    throw Error(who + ": rendezvous failed: " + oneLine(e));
  }

  // ---- The settings every rank must share, before any collective: a rank on another
  // material or with another seed would otherwise train on different data (or crash inside
  // Gloo on buffers of different sizes). Rank 0's list is the reference; each rank posts its
  // verdict, rank 0 collects them and posts the outcome, so every rank stops together.
  RendezvousClient& c = state_->store->client();
  const std::string agreed = "ok";
  c.set("nbtf/settings/" + std::to_string(rank), encodeList(config_.mustAgree));
  if (rank != 0) {
    std::string verdict;
    try {
      verdict = distributedMismatch(decodeList(c.get("nbtf/settings/0", deadline)), config_.mustAgree, rank);
    } catch (const std::exception& e) {
      throw Error(who + ": rendezvous failed: " + oneLine(e));
    }
    c.set("nbtf/verdict/" + std::to_string(rank), bytesOf(verdict.empty() ? agreed : "!" + verdict));
    if (!verdict.empty()) throw Error(who + ": " + verdict);
    std::string outcome;
    try {
      outcome = textOf(c.get("nbtf/outcome", deadline));
    } catch (const std::exception&) {
      throw Error(who + ": rendezvous failed: rank 0 did not confirm the settings within " + within + " (" + hint + ")");
    }
    c.set("nbtf/seen/" + std::to_string(rank), bytesOf(agreed));
    if (outcome != agreed) throw Error(who + ": " + outcome);
  } else {
    std::string problem, missing;
    std::vector<std::string> seen;
    for (int r = 1; r < world; ++r) {
      std::string verdict;
      try {
        verdict = textOf(c.get("nbtf/verdict/" + std::to_string(r), deadline));
      } catch (const Error&) {
        missing += (missing.empty() ? "" : ", ") + std::to_string(r);
        continue;
      }
      if (verdict == agreed) seen.push_back("nbtf/seen/" + std::to_string(r));
      if (verdict != agreed && problem.empty()) problem = verdict.substr(1);
    }
    if (problem.empty() && !missing.empty())
      problem = "rendezvous failed: rank " + missing + " did not join within " + within + " (" + hint + ")";
    c.set("nbtf/outcome", bytesOf(problem.empty() ? agreed : problem));
    if (!problem.empty()) {
      // The server goes with this rank: let the waiting ranks read the outcome first, so they
      // stop with it rather than with a lost connection (2 s at most).
      try {
        c.wait(seen, StoreClock::now() + std::chrono::seconds(2));
      } catch (const Error&) {
      }
      throw Error(who + ": " + problem);
    }
  }

  try {
    auto options = c10d::ProcessGroupGloo::Options::create(state_->timeout);
    // Gloo's transport listens on the interface that reaches the master (loopback for a
    // loopback master), not on every interface.
    options->devices.push_back(c10d::ProcessGroupGloo::createDeviceForHostname(localAddressTowards(host, port)));
    options->threads = 1;
    state_->store->limit(deadline);
    state_->group = c10::make_intrusive<c10d::ProcessGroupGloo>(state_->store, rank, world, options);
    state_->store->limit(std::nullopt);
  } catch (const std::exception& e) {
    throw Error(who + ": rendezvous failed within " + within + " (" + hint + "): " + oneLine(e));
  }
}

DistributedGroup::~DistributedGroup() = default;

void DistributedGroup::allReduceSum(torch::Tensor& values) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<at::Tensor> tensors{values};
  try {
    auto work = state_->group->allreduce(tensors);
    if (!work->wait(state_->timeout)) throw std::runtime_error("timed out");
  } catch (const std::exception& e) {
    throw Error("distributed training (rank " + std::to_string(config_.rank) + " of " +
                std::to_string(config_.worldSize) + "): a collective failed after " +
                std::to_string(secondsSince(start)) +
                " s (a peer stopped or is unreachable; timeout " +
                std::to_string(static_cast<int>(config_.timeoutSeconds)) + " s): " + oneLine(e));
  }
  seconds_ += secondsSince(start);
}

double DistributedGroup::allReduceGradients(const std::vector<torch::Tensor>& params, double value) {
  // Every rank has the same parameters in the same order; a gradient that is undefined on one
  // rank (a frozen part) is undefined on all, so the flat layouts match.
  std::vector<torch::Tensor> parts;
  for (const torch::Tensor& p : params)
    if (p.grad().defined()) parts.push_back(p.grad().reshape({-1}));
  parts.push_back(torch::full({1}, static_cast<float>(value)));
  torch::Tensor flat = torch::cat(parts).contiguous();
  allReduceSum(flat);
  std::int64_t offset = 0;
  for (const torch::Tensor& p : params) {
    if (!p.grad().defined()) continue;
    const std::int64_t n = p.grad().numel();
    p.grad().copy_(flat.narrow(0, offset, n).view_as(p.grad()));
    offset += n;
  }
  bytes_ += static_cast<double>(flat.numel()) * sizeof(float);
  ++calls_;
  return flat[offset].item<float>();
}

}  // namespace detail
}  // namespace nbtf
