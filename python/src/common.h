// Shared by the two extensions of the Python module (_nbtf, _nbtf_train): errors as Python
// exceptions, and progress bars as calls of a Python callable.
#pragma once
#include <pybind11/pybind11.h>

#include <atomic>
#include <cerrno>
#include <exception>
#include <memory>
#include <mutex>
#include <string>

#include "util/error.h"
#include "util/progress.h"

namespace nbtf::python {

namespace py = pybind11;

// FileAccessError -> OSError (FileNotFoundError, PermissionError, ... by its errno), with the
// message the command line prints and errno set; any other nbtf::Error -> ValueError.
inline void raiseOsError(const FileAccessError& e) {
  PyObject* type = PyExc_OSError;
  switch (e.errnum()) {
    case ENOENT: type = PyExc_FileNotFoundError; break;
    case EACCES:
    case EPERM: type = PyExc_PermissionError; break;
    case EISDIR: type = PyExc_IsADirectoryError; break;
    case ENOTDIR: type = PyExc_NotADirectoryError; break;
    case EEXIST: type = PyExc_FileExistsError; break;
    default: break;
  }
  const std::string message = userMessage(e);
  PyObject* value = PyObject_CallFunction(type, "s", message.c_str());
  if (!value) return;  // the call set its own error
  // errno only: with strerror or filename set, str() would print "[Errno N] ..." instead of
  // the command line's message (which names the file).
  if (e.errnum() != 0) {
    PyObject* errnum = PyLong_FromLong(e.errnum());
    PyObject_SetAttrString(value, "errno", errnum);
    Py_XDECREF(errnum);
  }
  PyErr_Clear();
  PyErr_SetObject(type, value);
  Py_DECREF(value);
}

inline void registerErrors() {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const FileAccessError& e) {
      raiseOsError(e);
    } catch (const Error& e) {
      PyErr_SetString(PyExc_ValueError, userMessage(e).c_str());
    }
  });
}

// Progress bars while a call runs with the GIL released: `callback` None keeps the terminal
// bars of the command line (quiet: none); a callable is called as callback(dict) with label,
// done, total, seconds, status, final, from whichever thread advances the bar. An exception
// raised by the callback (or a KeyboardInterrupt noticed there) is kept; `stop` (may be null)
// is set so that a long run stops early, and rethrow() raises it once the call is back.
class ProgressScope {
 public:
  ProgressScope(py::object callback, bool quiet, std::atomic<bool>* stop = nullptr)
      : callback_(std::move(callback)), stop_(stop), wasQuiet_(Progress::quiet()) {
    Progress::setQuiet(quiet);
    if (callback_.is_none()) return;
    auto state = state_;
    py::object cb = callback_;
    std::atomic<bool>* flag = stop_;
    Progress::setListener([state, cb, flag](const Progress::Update& u) {
      if (state->failed) return;
      py::gil_scoped_acquire gil;
      try {
        py::dict d;
        d["label"] = u.label;
        d["done"] = u.done;
        d["total"] = u.total;
        d["seconds"] = u.seconds;
        d["status"] = u.status;
        d["final"] = u.final;
        cb(d);
        if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      } catch (py::error_already_set& e) {
        std::lock_guard<std::mutex> lock(state->mutex);
        if (!state->failed) {
          state->error = std::make_unique<py::error_already_set>(std::move(e));
          state->failed = true;
        }
        if (flag) flag->store(true);
      }
    });
  }
  ~ProgressScope() {
    Progress::setListener(nullptr);
    Progress::setQuiet(wasQuiet_);
    state_->error.reset();  // Python objects: the scope ends with the GIL held
  }
  ProgressScope(const ProgressScope&) = delete;
  ProgressScope& operator=(const ProgressScope&) = delete;

  bool failed() const { return state_->failed; }
  // Raises the callback's exception, if it raised one (call with the GIL held).
  void rethrow() {
    if (!state_->failed) return;
    std::unique_ptr<py::error_already_set> e = std::move(state_->error);
    if (e) throw std::move(*e);
  }

 private:
  struct State {
    std::mutex mutex;
    std::atomic<bool> failed{false};
    std::unique_ptr<py::error_already_set> error;
  };
  py::object callback_;
  std::atomic<bool>* stop_;
  bool wasQuiet_;
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

}  // namespace nbtf::python
