// Data-parallel training across processes on libtorch's own distributed engine (c10d): a
// TCPStore rendezvous at the master's address and a ProcessGroupGloo. Every step each rank
// trains on its share of the step's tiles (encoder inputs x images), the gradients are summed
// over the ranks (weighted by their sample counts, so the update is the one of the whole
// step), and every rank applies the same optimizer step. Rank 0 writes the file.
// This header is torch-free; docs/model.md, *Data-parallel training*.
#pragma once
#include <string>

namespace nbtf {

struct DistributedConfig {
  int worldSize = 1;            // processes; 1 = not distributed
  int rank = 0;                 // this process, 0..worldSize-1; rank 0 is the master and writes
  std::string master;           // "HOST:PORT" of rank 0's rendezvous (TCPStore)
  double timeoutSeconds = 120;  // rendezvous and every collective: a peer that stops is an error, not a hang
  bool enabled() const { return worldSize > 1; }
};

// Throws nbtf::Error naming the option when the settings are inconsistent.
void validateDistributedConfig(const DistributedConfig& config);

// The tiles [begin, end) of a step's `tiles` that `rank` of `worldSize` trains on: contiguous,
// as even as possible (the first tiles % worldSize ranks get one more).
void tileShare(int tiles, int rank, int worldSize, int& begin, int& end);

}  // namespace nbtf
