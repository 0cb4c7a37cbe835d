#include "model/distributed.h"

#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <torch/csrc/distributed/c10d/TCPStore.hpp>

#include <chrono>
#include <cmath>

#include "model/distributed_group.h"
#include "util/error.h"

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

void tileShare(int tiles, int rank, int worldSize, int& begin, int& end) {
  const int base = tiles / worldSize, extra = tiles % worldSize;
  begin = rank * base + std::min(rank, extra);
  end = begin + base + (rank < extra ? 1 : 0);
}

namespace detail {

struct DistributedGroup::State {
  c10::intrusive_ptr<c10d::Store> store;
  c10::intrusive_ptr<c10d::ProcessGroupGloo> group;
  std::chrono::milliseconds timeout{0};
};

DistributedGroup::DistributedGroup(const DistributedConfig& config) : config_(config), state_(new State) {
  validateDistributedConfig(config);
  std::string host;
  int port = 0;
  splitMaster(config.master, host, port);
  state_->timeout = std::chrono::milliseconds(static_cast<long long>(config.timeoutSeconds * 1000));
  const std::string who = "distributed training (rank " + std::to_string(config.rank) + " of " +
                          std::to_string(config.worldSize) + ", master " + config.master + ")";
  try {
    c10d::TCPStoreOptions so;
    so.port = static_cast<std::uint16_t>(port);
    so.isServer = config.rank == 0;
    so.numWorkers = static_cast<std::size_t>(config.worldSize);
    so.waitWorkers = true;
    so.timeout = state_->timeout;
    state_->store = c10::make_intrusive<c10d::TCPStore>(host, so);
    auto options = c10d::ProcessGroupGloo::Options::create(state_->timeout);
    // The transport binds to the master's interface on loopback (tests, one machine), else to
    // the interface of this host's name.
    const bool loopback = host == "127.0.0.1" || host == "localhost";
    options->devices.push_back(loopback ? c10d::ProcessGroupGloo::createDeviceForHostname("127.0.0.1")
                                        : c10d::ProcessGroupGloo::createDefaultDevice());
    options->threads = 1;
    state_->group = c10::make_intrusive<c10d::ProcessGroupGloo>(state_->store, config.rank, config.worldSize, options);
  } catch (const std::exception& e) {
    throw Error(who + ": rendezvous failed within " + std::to_string(static_cast<int>(config.timeoutSeconds)) +
                " s (are all ranks started with the same --master and --world-size?): " + e.what());
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
                std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()) +
                " s (a peer stopped or is unreachable; timeout " +
                std::to_string(static_cast<int>(config_.timeoutSeconds)) + " s): " + e.what());
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
