// Little-endian binary files: a byte writer, and one bounds-checked reader for every binary
// format nbtf reads (.nbtf sections, checkpoints, UBO2014 .btf). The reader never touches a
// byte past its end: every read checks the remaining size first and throws an nbtf::Error
// naming the file, what is being read, the field and the file offset. A declared count is
// checked against the bytes left before anything is allocated for it.
#pragma once
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <type_traits>
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

// Reads from a buffer in memory, or from a file (ByteReader::openFile) without loading it:
// files of many GB are read field by field and array by array.
class ByteReader {
 public:
  // Over `size` bytes at `data`; `base` is the offset of data[0] within the file, so errors
  // report file offsets.
  ByteReader(const std::uint8_t* data, std::size_t size, std::string file, std::string what, std::size_t base = 0)
      : data_(data), size_(size), file_(std::move(file)), what_(std::move(what)), base_(base) {}

  // Over the whole file at `path`, read as it goes; an error names `path` (a missing file,
  // one that cannot be opened or sized).
  static ByteReader openFile(const std::string& path, std::string what) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw fileAccessError(path, "no such file", ENOENT);
    auto in = std::make_unique<std::ifstream>(path, std::ios::binary);
    if (!*in) throw fileAccessError(path, "cannot open for reading", errno);
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (ec) throw fileAccessError(path, "cannot read the file size: " + ec.message(), ec.value());
    ByteReader r(nullptr, static_cast<std::size_t>(size), path, std::move(what));
    r.stream_ = std::move(in);
    return r;
  }

  std::size_t remaining() const { return size_ - pos_; }
  std::size_t position() const { return pos_; }
  std::size_t size() const { return size_; }
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
  // One little-endian scalar (integer or IEEE float), named in errors as `field`.
  template <class T>
  T value(const std::string& field) {
    static_assert(std::is_arithmetic_v<T>, "value<T>: a number");
    using Bits = std::conditional_t<sizeof(T) == 1, std::uint8_t,
                                    std::conditional_t<sizeof(T) == 2, std::uint16_t,
                                                       std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;
    static_assert(sizeof(Bits) == sizeof(T), "value<T>: 1, 2, 4 or 8 bytes");
    const auto bits = static_cast<Bits>(le(sizeof(T), field.c_str()));
    T v;
    std::memcpy(&v, &bits, sizeof(T));
    return v;
  }
  // The next `n` bytes (checked), advancing past them. In memory: a pointer into the buffer;
  // from a file: into the reader's own buffer, valid until the next read.
  const std::uint8_t* take(std::size_t n, const char* field) {
    need(n, field);
    const std::uint8_t* p = fetch(n, field);
    pos_ += n;
    return p;
  }
  std::string text(std::size_t n, const std::string& field) {
    const std::uint8_t* p = take(n, field.c_str());
    return std::string(reinterpret_cast<const char*>(p), n);
  }
  // Moves to `position` bytes from the start (at most the end).
  void seek(std::size_t position) {
    if (position > size_) throw fail("seek past the end, to " + std::to_string(base_ + position));
    pos_ = position;
    if (stream_) {
      stream_->clear();
      stream_->seekg(static_cast<std::streamoff>(position));
    }
  }
  // Checks that `count` items of `itemBytes` each are present, before anything is allocated
  // for them: a hostile count can never make the reader allocate more than the file holds.
  void needItems(std::uint64_t count, std::size_t itemBytes, const std::string& field) const {
    if (itemBytes != 0 && count > remaining() / itemBytes) {
      throw fail(field + " declares " + std::to_string(count) + " items of " + std::to_string(itemBytes) +
                 " bytes, but only " + std::to_string(remaining()) + " bytes remain");
    }
  }
  void need(std::uint64_t n, const std::string& field) const {
    if (n > remaining())
      throw fail("truncated while reading " + field + ": needs " + std::to_string(n) + " bytes, only " +
                 std::to_string(remaining()) + " remain");
  }
  // An error at the current position: "file: <what> at file offset N: message".
  Error fail(const std::string& message) const {
    return fileError(file_, what_ + " at file offset " + std::to_string(fileOffset()) + ": " + message);
  }

 private:
  const std::uint8_t* fetch(std::size_t n, const char* field) {
    if (!stream_) return data_ + pos_;
    buffer_.resize(n);
    stream_->read(reinterpret_cast<char*>(buffer_.data()), static_cast<std::streamsize>(n));
    if (!*stream_) throw fail(std::string("read error while reading ") + field);
    return buffer_.data();
  }
  std::uint64_t le(std::size_t n, const char* field) {
    const std::uint8_t* p = take(n, field);
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < n; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
    return v;
  }
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string file_, what_;
  std::size_t base_;
  std::unique_ptr<std::ifstream> stream_;  // set: reading a file as it goes
  std::vector<std::uint8_t> buffer_;       // the last bytes read from stream_
};

}  // namespace nbtf
