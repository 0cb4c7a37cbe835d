// The c10d process group of a distributed training run. PRIVATE to src/model/
// (includes torch).
#pragma once
#include <torch/torch.h>

#include <memory>
#include <vector>

#include "model/distributed/distributed.h"

namespace nbtf::detail {

class DistributedGroup {
 public:
  // Rendezvous with the other ranks (rank 0 hosts the TCPStore); throws nbtf::Error naming the
  // master and the rank when it fails or times out.
  explicit DistributedGroup(const DistributedConfig& config);
  ~DistributedGroup();

  int rank() const { return config_.rank; }
  int worldSize() const { return config_.worldSize; }

  // Sums `values` (float32, CPU, contiguous) over the ranks in place, on every rank.
  void allReduceSum(torch::Tensor& values);
  // Sums every defined gradient of `params`, and `value` (the step's loss share), over the
  // ranks in one flat message; returns the summed value.
  double allReduceGradients(const std::vector<torch::Tensor>& params, double value);
  // Bytes sent per allReduceGradients so far and the calls (for the summary and benchmarks).
  double bytesReduced() const { return bytes_; }
  long calls() const { return calls_; }
  double secondsInCollectives() const { return seconds_; }

 private:
  struct State;
  DistributedConfig config_;
  std::unique_ptr<State> state_;
  double bytes_ = 0, seconds_ = 0;
  long calls_ = 0;
};

}  // namespace nbtf::detail
