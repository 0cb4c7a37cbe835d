// libtorch logs through glog; glog used before it is initialized prints "WARNING: Logging
// before InitGoogleLogging() is written to STDERR" and, once initialized, writes log files
// under /tmp. nbtf reports its own errors: glog is initialized to write errors only, to
// stderr, and no files. PRIVATE to src/model/.
#pragma once

namespace nbtf::detail {

// Idempotent and thread-safe; called before libtorch's distributed and training code runs.
void quietTorchLogging();

}  // namespace nbtf::detail
