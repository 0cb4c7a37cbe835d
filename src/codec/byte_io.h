// Little-endian byte writer and a bounds-checked reader for the .nbtf file. The reader
// never touches a byte past its end: every read checks the remaining size first and
// throws an nbtf::Error naming the file, the section and the offset.
#pragma once
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "util/error.h"

namespace nbtf {

class ByteWriter {
 public:
  void u8(std::uint8_t v) { bytes_.push_back(v); }
  void u16(std::uint16_t v) { le(v, 2); }
  void u32(std::uint32_t v) { le(v, 4); }
  void u64(std::uint64_t v) { le(v, 8); }
  void f32(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, 4);
    u32(bits);
  }
  void f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, 8);
    u64(bits);
  }
  void raw(const void* data, std::size_t size) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + size);
  }
  void zeros(std::size_t n) { bytes_.insert(bytes_.end(), n, 0); }
  // Overwrites 4 / 8 bytes at `offset` (for sizes and checksums known only later).
  void patchU32(std::size_t offset, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes_[offset + i] = static_cast<std::uint8_t>(v >> (8 * i));
  }
  void patchU64(std::size_t offset, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) bytes_[offset + i] = static_cast<std::uint8_t>(v >> (8 * i));
  }
  std::size_t size() const { return bytes_.size(); }
  std::vector<std::uint8_t>& bytes() { return bytes_; }

 private:
  void le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) bytes_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t> bytes_;
};

class ByteReader {
 public:
  // `base` is the offset of data[0] within the file, so errors report file offsets.
  ByteReader(const std::uint8_t* data, std::size_t size, std::string file, std::string what, std::size_t base = 0)
      : data_(data), size_(size), file_(std::move(file)), what_(std::move(what)), base_(base) {}

  std::size_t remaining() const { return size_ - pos_; }
  std::size_t position() const { return pos_; }
  std::size_t fileOffset() const { return base_ + pos_; }

  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1, "u8")); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2, "u16")); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4, "u32")); }
  std::uint64_t u64() { return le(8, "u64"); }
  float f32() {
    std::uint32_t bits = u32();
    float v;
    std::memcpy(&v, &bits, 4);
    return v;
  }
  double f64() {
    std::uint64_t bits = u64();
    double v;
    std::memcpy(&v, &bits, 8);
    return v;
  }
  // A pointer to the next `n` bytes (checked), advancing past them.
  const std::uint8_t* take(std::size_t n, const char* field) {
    need(n, field);
    const std::uint8_t* p = data_ + pos_;
    pos_ += n;
    return p;
  }
  // Checks that `count` items of `itemBytes` each are present, before anything is allocated
  // for them: a hostile count can never make the reader allocate more than the file holds.
  void needItems(std::uint64_t count, std::size_t itemBytes, const char* field) const {
    if (itemBytes != 0 && count > remaining() / itemBytes) {
      throw fail(std::string(field) + " declares " + std::to_string(count) + " items of " +
                 std::to_string(itemBytes) + " bytes, but only " + std::to_string(remaining()) +
                 " bytes remain in the section");
    }
  }
  void need(std::size_t n, const char* field) const {
    if (n > remaining())
      throw fail(std::string("truncated while reading ") + field + ": needs " + std::to_string(n) +
                 " bytes, only " + std::to_string(remaining()) + " remain");
  }
  // An error at the current position: "file: section 'X' at offset N: message".
  Error fail(const std::string& message) const {
    return fileError(file_, what_ + " at file offset " + std::to_string(fileOffset()) + ": " + message);
  }

 private:
  std::uint64_t le(int n, const char* field) {
    need(static_cast<std::size_t>(n), field);
    std::uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= static_cast<std::uint64_t>(data_[pos_ + i]) << (8 * i);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string file_, what_;
  std::size_t base_;
};

}  // namespace nbtf
