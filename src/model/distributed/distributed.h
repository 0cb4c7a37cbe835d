// Data-parallel training across processes on libtorch's own distributed engine (c10d): a
// rendezvous store hosted by rank 0 at the master's address (model/distributed/rendezvous_store.h: bound
// to that address only, every peer presents the run's shared secret) and a ProcessGroupGloo. Every step each rank
// trains on its share of the step's tiles (encoder inputs x images), the gradients are summed
// over the ranks (weighted by their sample counts, so the update is the one of the whole
// step), and every rank applies the same optimizer step. Rank 0 writes the file.
// This header is torch-free; docs/model.md, *Data-parallel training*.
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace nbtf {

struct DistributedConfig {
  int worldSize = 1;            // processes; 1 = not distributed
  int rank = 0;                 // this process, 0..worldSize-1; rank 0 is the master and writes
  std::string master;           // "HOST:PORT" of rank 0's rendezvous (TCPStore)
  double timeoutSeconds = 120;  // rendezvous and every collective: a peer that stops is an error, not a hang
  // Shared by every rank of a run (--dist-secret / NBTF_DIST_SECRET); a peer that does not
  // present it can neither join nor read or write the rendezvous.
  std::string secret;
  // What must be the same on every rank, in the order checked: (name as the user knows it,
  // e.g. "--seed", value). At the rendezvous every rank compares its list with rank 0's, and
  // all ranks stop with an error naming the first entry that differs.
  std::vector<std::pair<std::string, std::string>> mustAgree;
  bool enabled() const { return worldSize > 1; }
};

// Throws nbtf::Error naming the option when the settings are inconsistent.
void validateDistributedConfig(const DistributedConfig& config);

// Fills config.secret from NBTF_DIST_SECRET when it is empty. Still empty: rank 0 generates
// one and prints it on stderr with how to pass it to the other ranks; another rank gets an
// nbtf::Error saying how to pass rank 0's. Does nothing when not distributed.
void completeDistributedSecret(DistributedConfig& config);

// The first entry of `mine` that differs from `reference` (rank 0's), as "NAME differs:
// rank 0 has A, rank R has B"; "" when they agree.
std::string distributedMismatch(const std::vector<std::pair<std::string, std::string>>& reference,
                                const std::vector<std::pair<std::string, std::string>>& mine, int rank);

// The tiles [begin, end) of a step's `tiles` that `rank` of `worldSize` trains on: contiguous,
// as even as possible (the first tiles % worldSize ranks get one more).
void tileShare(int tiles, int rank, int worldSize, int& begin, int& end);

}  // namespace nbtf
