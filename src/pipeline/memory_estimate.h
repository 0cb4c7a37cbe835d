// How much memory a run will take, estimated before the stack is loaded, and the check of
// --memory-limit (docs/compress.md, *Memory*). The clustered pipeline streams the ABRDF matrix
// from the stack (preprocess/abrdf_source.h), so its peak is the stack plus working sets that
// grow with texels x (PCA sketch + components), 3N x (sketch + a few tables) and one cluster's
// ABRDFs per thread, not with texels x 3N; the per-texel mode and the PCA baseline hold the
// M x 3N float32 matrix.
#pragma once
#include <cstddef>
#include <string>

#include "io/btf_loader.h"
#include "util/scratch_mapping.h"

namespace nbtf {

struct MemoryEstimate {
  std::size_t stack = 0;    // the loaded stack (8-bit or half), or its resident window when in a scratch file
  std::size_t working = 0;  // the largest working set after loading (the stage named below)
  std::size_t process = 0;  // the program itself: libraries (libtorch, OpenCV, BLAS), allocator slack
  std::string stage;        // where the working set peaks
  bool stackInScratchFile = false;  // the stack's samples in a scratch file (withStackInScratchFile)
  std::size_t total() const { return stack + working + process; }
};

// The clustered pipeline with k clusters (k > 0), the per-texel mode (k = 0), or the PCA
// baseline (pcaBaseline), on `workers` threads. components: PCA components before k-means;
// coefficientsPerTexel: the per-texel modulation's (terms x channels; 1 without).
MemoryEstimate estimateCompressMemory(const StackShape& shape, int clusters, bool pcaBaseline, int components,
                                      int oversampling, int coefficientsPerTexel, int workers);
// The same estimate with the stack's samples in a scratch file (util/scratch_mapping.h): the
// stack counts as its resident budget and what one trim interval may add, at most the stack.
MemoryEstimate withStackInScratchFile(MemoryEstimate estimate);
constexpr std::size_t kScratchResidentWindow = ScratchMapping::kDefaultResidentBudget + (std::size_t(256) << 20);
// Where an image stack's samples live (docs/compress.md, *A stack in a scratch file*): Auto puts
// them in a scratch file only when the run would not fit in the memory limit with them in
// memory but fits with them in a file; Memory and File force one. scratchDir: the file's
// folder ("" = the command's default, e.g. the output's folder).
enum class StackStorage { Auto, Memory, File };
struct StackStorageOptions {
  StackStorage storage = StackStorage::Auto;
  std::string scratchDir;
};
// The folder of the stack's scratch file for this run, or "" to keep the stack in memory; with a
// folder, `estimate` becomes withStackInScratchFile's. Never a file for a UBO2014 input (it is
// expanded or computed, not stored from images); Auto never onto a file system in memory (tmpfs:
// the file would take the same memory). With `announce`, says on stderr why the stack goes to a
// file (Auto) or warns about tmpfs (File).
std::string stackScratchDir(const StackStorageOptions& options, const std::string& defaultDir,
                            const std::string& input, MemoryEstimate& estimate, std::size_t limit, bool announce);
// `nbtf cluster` (no training; the texel colour images); pcaSampleBytes: PcaOptions::sampleBytes.
MemoryEstimate estimateClusterMemory(const StackShape& shape, int clusters, int components, int oversampling,
                                     int workers, std::size_t pcaSampleBytes);

// Throws nbtf::Error naming the input, its shape, the estimate and the limit when the estimate
// is above `limit`; `limitText` says where the limit came from (e.g. "--memory-limit 8G").
void enforceMemoryLimit(const MemoryEstimate& estimate, std::size_t limit, const std::string& limitText,
                        const std::string& input, const StackShape& shape);

// The stack's place and the memory check of one run, both before any image is read: the
// scratch folder (stackScratchDir, under `defaultDir`; `estimate` then counts the stack in it),
// then enforceMemoryLimit (`limitText` "" = the default limit's description). Returns the
// scratch folder ("" = memory).
std::string placeStackWithinLimit(const StackStorageOptions& storage, const std::string& defaultDir,
                                  const std::string& input, const StackShape& shape, MemoryEstimate& estimate,
                                  std::size_t limit, const std::string& limitText, bool announce);

// The largest half-float expansion of a UBO2014 file (LoadOptions::expandUpTo) a run under
// `limit` makes: half the limit. A larger one stays factorized, its values computed when read
// (the same values, slower to read).
inline std::size_t expandBudget(std::size_t limit) { return limit / 2; }

// "the default --memory-limit (75% of the 23.4 GiB of physical memory)" or "--memory-limit 8G".
std::string memoryLimitText(bool given, const std::string& value);

}  // namespace nbtf
