// Memory sizes: parsing "16G"-style options, the machine's physical memory, the process's peak.
#pragma once
#include <cstddef>
#include <string>

namespace nbtf {

// "123", "800K", "16M", "12G", "1.5G" (binary units: K = 1024; a trailing "B" or "iB" is allowed).
// Throws nbtf::Error naming `option` when the text is not a positive size.
std::size_t parseByteSize(const std::string& text, const std::string& option);

// MemTotal from /proc/meminfo; 0 when unknown.
std::size_t physicalMemoryBytes();

// The default memory limit: 75% of physical memory (8 GiB when it cannot be read).
std::size_t defaultMemoryLimit();

// Peak resident set size of this process so far (getrusage ru_maxrss), bytes.
std::size_t peakResidentBytes();

// Keeps freed memory in the process for the next allocation instead of handing it back to the
// system at once (glibc: blocks up to 64 MiB come from the heap, whose top is handed back
// only past 256 MiB). Memory the system hands out afresh is zeroed page by page on first
// touch, and on virtual machines each such fault is slow: a stage that allocates a few MiB
// per image or per batch spent more time faulting than computing (loading 6561 PNGs of
// 800 x 800 took 158 s, 53 s with this). Call once, at the start of a program; a no-op where
// the C library is not glibc.
void reuseFreedMemory();

// "6.17 GiB", "820 MiB", "12 KiB".
std::string formatBytes(std::size_t bytes);

}  // namespace nbtf
