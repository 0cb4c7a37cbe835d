#include "model/autograd/torch_logging.h"

#include <mutex>

#ifdef NBTF_HAVE_GLOG
#include <glog/logging.h>
#endif

namespace nbtf::detail {

void quietTorchLogging() {
#ifdef NBTF_HAVE_GLOG
  static std::once_flag once;
  std::call_once(once, [] {
    FLAGS_logtostderr = true;  // no log files
    FLAGS_minloglevel = 2;     // ERROR and FATAL only
    if (!google::IsGoogleLoggingInitialized()) google::InitGoogleLogging("nbtf");
  });
#endif
}

}  // namespace nbtf::detail
