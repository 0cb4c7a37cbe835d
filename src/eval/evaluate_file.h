// `nbtf eval` without its command line: a .nbtf file compared with the measured stack it was
// made from (the reference cut the way the file was, its source fingerprint checked), the
// evaluation of eval/evaluate.h on it. The command line and the Python module's
// nbtf.evaluate call this; writing the report (eval/report.h) is theirs.
#pragma once
#include <optional>
#include <string>

#include "codec/nbtf_file.h"
#include "eval/evaluate.h"
#include "io/btf_stack.h"
#include "util/layout.h"

namespace nbtf {

struct EvaluateFileOptions {
  EvalOptions eval;
  std::optional<Crop> crop;      // of the reference (default: the file's crop)
  std::optional<Layout> layout;  // of the reference (default: the file's)
  bool force = false;            // evaluate a reference that does not match the file's source fingerprint
  std::string renderCompare;     // the folder `nbtf render --compare` wrote, shown in the report ("" = none)
  bool groundTruth = true;       // also measure against the float ground truth beside the reference, when there is one
};

struct EvaluateFileResult {
  EvalResult result;
  int evaluationsPerImage = 0;  // decoder evaluations per image: k (clustered) or texels
};

// The reference must be the material the file was made from: its per-image means and texel
// pattern are compared with the file's source fingerprint (io/source_fingerprint.h). Throws
// nbtf::Error naming both when they differ, unless `force` (then a warning on stderr, prefixed
// with `program`). Returns the line a report states ("matches ...", "MISMATCH, used anyway ...",
// "not checked: ...").
std::string checkReferenceFingerprint(const CompressedBtf& btf, const BtfStack& reference, const std::string& file,
                                      const std::string& referencePath, bool force, const std::string& program);

// Throws nbtf::Error naming the file or the reference and what is wrong: an unreadable file,
// a reference of another size or other directions, or one that is not the material the file
// was made from (unless force; then a warning on stderr and the report says so).
EvaluateFileResult evaluateFile(const std::string& file, const std::string& referencePath,
                                const EvaluateFileOptions& options);

}  // namespace nbtf
