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

// "6.17 GiB", "820 MiB", "12 KiB".
std::string formatBytes(std::size_t bytes);

}  // namespace nbtf
