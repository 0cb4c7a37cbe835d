// Errors: every failure a user can cause is an nbtf::Error whose message names
// the file (and line or field) and what is wrong. Front ends print it and exit 1.
#pragma once
#include <stdexcept>
#include <string>

namespace nbtf {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// "path: message", the form every file-related error takes.
inline Error fileError(const std::string& path, const std::string& message) {
  return Error(path + ": " + message);
}

}  // namespace nbtf
