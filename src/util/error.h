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

// A file or folder that cannot be reached, read or written (missing, not a folder, no
// permission, disk full), as opposed to one whose contents are wrong (a plain Error). The
// command line prints both alike; the Python module raises OSError for this one and
// ValueError for the others. `errnum` is the errno value that says why (0 = none fits).
class FileAccessError : public Error {
 public:
  FileAccessError(const std::string& path, const std::string& message, int errnum)
      : Error(path + ": " + message), path_(path), errnum_(errnum) {}
  const std::string& path() const { return path_; }
  int errnum() const { return errnum_; }

 private:
  std::string path_;
  int errnum_;
};

inline FileAccessError fileAccessError(const std::string& path, const std::string& message, int errnum) {
  return FileAccessError(path, message, errnum);
}

// The text of an exception as a user reads it: one line per line of the message, without
// the stack trace libtorch appends to its c10::Error ("Exception raised from F at FILE:LINE
// (most recent call first):" and a frame per line). An internal check keeps its place:
// "message (internal check at FILE:LINE)".
inline std::string userMessage(const std::exception& e) {
  std::string text = e.what();
  const std::string marker = "\nException raised from ";
  const auto at = text.find(marker);
  if (at == std::string::npos) return text.substr(0, text.find("\nframe #"));
  std::string where = text.substr(at + marker.size());
  where = where.substr(0, where.find('\n'));
  const auto file = where.find(" at "), end = where.find(" (most recent");
  text = text.substr(0, at);
  if (file != std::string::npos) text += " (internal check at " + where.substr(file + 4, end == std::string::npos ? std::string::npos : end - file - 4) + ")";
  return text;
}

}  // namespace nbtf
