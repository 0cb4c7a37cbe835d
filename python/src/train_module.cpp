// _nbtf_train: the half of the Python module `nbtf` that links the training pipeline
// (libtorch) and the evaluation: nbtf.compress and nbtf.evaluate import it, nothing else does.
//
// compress takes the command line's own option set (apps/options/compress_options.h):
// __init__.py turns keyword arguments into "--name=value" and the options of `nbtf compress`
// parse them into the same CompressOptions, so names, defaults, checks and messages are the
// command line's.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <future>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cli_common.h"
#include "common.h"
#include "eval/evaluate_file.h"
#include "eval/report.h"
#include "options/compress_options.h"
#include "pipeline/compressor.h"
#include "util/atomic_file.h"
#include "util/parallel.h"

namespace nbtf::python {
namespace {

// Restores the thread count and quietness a command line run sets for the whole process.
class GlobalsScope {
 public:
  GlobalsScope() : threads_(threadCount()), quiet_(Progress::quiet()) {}
  ~GlobalsScope() {
    setThreadCount(threads_);
    Progress::setQuiet(quiet_);
  }

 private:
  int threads_;
  bool quiet_;
};

// Runs `work` on its own thread with the GIL released; the calling thread looks for signals
// (Ctrl-C) every 100 ms and sets `stop` when one arrives, then waits for the work to end.
// Returns whether a signal arrived.
template <class Work>
bool runInterruptible(Work work, std::atomic<bool>& stop) {
  std::packaged_task<void()> task(std::move(work));
  std::future<void> done = task.get_future();
  std::thread worker(std::move(task));
  bool signalled = false;
  while (true) {
    std::future_status status;
    {
      py::gil_scoped_release release;
      status = done.wait_for(std::chrono::milliseconds(100));
    }
    if (status == std::future_status::ready) break;
    if (!signalled && PyErr_CheckSignals() != 0) {
      signalled = true;
      stop.store(true);
      std::fprintf(stderr, "\nnbtf.compress: interrupt received, stopping after a checkpoint\n");
    }
  }
  worker.join();
  // The signal's own exception is dropped: the caller reports the interruption (or the work's
  // error, which wins).
  if (signalled) PyErr_Clear();
  done.get();
  return signalled;
}

// args: the command line after "nbtf compress" (<input> -o <out> --name=value ...).
// Returns the --stats-json summary as JSON text; None after --help.
py::object compress(const std::vector<std::string>& args, py::object progress) {
  GlobalsScope globals;
  cxxopts::Options options("nbtf compress", "Compress a BTF image stack into a .nbtf file");
  options.positional_help("<input> -o <out.nbtf>");
  cli::addCompressOptions(options);
  std::vector<std::string> words{"nbtf compress"};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(w.data());
  argv.push_back(nullptr);
  cxxopts::ParseResult parsed;
  if (!cli::parseCommand(options, "input", static_cast<int>(words.size()), argv.data(), parsed)) return py::none();
  cli::CompressRequest request = cli::compressRequest(parsed, "nbtf.compress");
  cli::prepareCompressOutputs(request);
  CompressOptions& o = request.options;
  if (o.train.resume) {
    std::error_code ec;
    if (std::filesystem::exists(o.train.checkpointPath, ec))
      std::fprintf(stderr, "nbtf.compress: resuming from %s\n", o.train.checkpointPath.c_str());
    else
      std::fprintf(stderr, "nbtf.compress: resume: no checkpoint at %s, starting from the beginning\n",
                   o.train.checkpointPath.c_str());
  }
  std::atomic<bool> stop{false};
  o.stopFlag = &stop;
  ProgressScope scope(progress, Progress::quiet(), &stop);
  CompressStats stats;
  runInterruptible([&] { stats = compressBtf(request.input, request.output, o); }, stop);
  scope.rethrow();
  if (!request.statsPath.empty()) writeFileAtomic(request.statsPath, compressStatsJson(stats));
  if (stats.interrupted) {
    std::error_code ec;
    const bool checkpoint = !stats.checkpointPath.empty() && std::filesystem::exists(stats.checkpointPath, ec);
    PyErr_SetString(PyExc_KeyboardInterrupt,
                    ("nbtf.compress: interrupted; nothing written to " + request.output +
                     (checkpoint ? ". Training state is in " + stats.checkpointPath +
                                       ": call compress again with resume=True to continue."
                                 : "."))
                        .c_str());
    throw py::error_already_set();
  }
  return py::str(compressStatsJson(stats));
}

// `nbtf eval` (the report's JSON as text); the report files too where `output` is given.
std::string evaluate(const std::string& file, const std::string& reference, const std::string& output,
                     const std::string& crop, const std::string& layout, int blurImages, bool force,
                     const std::string& renderCompare, py::object progress, bool quiet, int threads) {
  GlobalsScope globals;
  setThreadCount(threads);
  EvaluateFileOptions o;
  o.eval.blurSampleImages = blurImages;
  if (blurImages < 0) throw Error("--blur-images must be >= 0");
  o.eval.progress = !quiet || !progress.is_none();  // quiet silences the text bars, not a callback
  if (!crop.empty()) o.crop = parseCrop(crop);
  if (!layout.empty()) o.layout = parseLayout(layout);
  o.force = force;
  o.renderCompare = renderCompare;
  if (!output.empty()) {
    refuseOverlappingPaths({{"<file.nbtf>", file},
                            {"--reference", reference},
                            {"--render-compare", renderCompare}},
                           {{"-o", output, true}});
    cli::checkFolderCreatable(output);
  }
  ProgressScope scope(progress, quiet);
  EvalResult result;
  {
    py::gil_scoped_release release;
    result = std::move(evaluateFile(file, reference, o).result);
    if (!output.empty()) writeReport(result, output);
  }
  scope.rethrow();
  return reportJson(result).dump();
}

}  // namespace
}  // namespace nbtf::python

PYBIND11_MODULE(_nbtf_train, m) {
  using namespace nbtf::python;
  m.doc() = "nbtf's compressor and evaluation (libtorch); use nbtf.compress and nbtf.evaluate";
  registerErrors();
  m.def("compress", &compress, py::arg("args"), py::arg("progress"));
  // The long names of `nbtf compress`'s options, for nbtf.compress's keyword check.
  m.def("compress_options", [] {
    cxxopts::Options options("nbtf compress");
    nbtf::cli::addCompressOptions(options);
    nbtf::cli::addCommonOptions(options);
    std::vector<std::string> names;
    for (const std::string& group : options.groups())
      for (const auto& o : options.group_help(group).options)
        for (const std::string& name : o.l) names.push_back(name);
    return names;
  });
  m.def("evaluate", &evaluate, py::arg("file"), py::arg("reference"), py::arg("output"), py::arg("crop"),
        py::arg("layout"), py::arg("blur_images"), py::arg("force"), py::arg("render_compare"), py::arg("progress"),
        py::arg("quiet"), py::arg("threads"));
  m.def("set_threads", [](int threads) { nbtf::setThreadCount(threads); }, py::arg("threads"));
}
