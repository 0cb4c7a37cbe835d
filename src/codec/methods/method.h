// A model kind (a "method"): how a material is represented, behind one interface. Each kind is
// one component file beside this header (clustered.cpp, per_texel.cpp, pca.cpp) and one row of
// the registry (method.cpp), found by the method code the file stores. A kind supplies what
// every consumer of a material asks of it: its name and descriptions, the parts it stores (its
// column of the section table's needs, codec/nbtf_sections.h), its invariants, and the
// evaluator the decoder holds. Adding a kind: docs/architecture.md.
//
// The compressor that makes a kind lives in pipeline/ (the decoder library has no training);
// the GLSL builder in shader/ (the decoder library has no shader text): each is one row of its
// stage's table, keyed by the same code.
#pragma once
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "codec/nbtf_file.h"
#include "codec/nbtf_sections.h"

namespace nbtf {

enum class DecoderIsa;
struct DecoderOptions;

namespace detail {
class MaterialEvaluator;
}

class MethodKind {
 public:
  // `name`: the stored name ("clustered-neural", "per-texel-neural", "pca"); `shortName`: who
  // needs a part only this kind has, in "required by the X method" ("clustered", "PCA").
  MethodKind(CodecMethod code, const char* name, const char* shortName)
      : code_(code), name_(name), shortName_(shortName) {}
  virtual ~MethodKind() = default;

  CodecMethod code() const { return code_; }
  const char* name() const { return name_; }
  const char* shortName() const { return shortName_; }

  // Which parts this kind stores: required ones a file must hold, forbidden ones it must not.
  virtual format::Need need(format::Part part) const = 0;

  // `nbtf info`'s method line: "clustered-neural, k = 1000 clusters".
  virtual std::string summary(const CompressedBtf& btf) const = 0;
  // `nbtf info`'s lines about the kind's own parts (name, value), after the material's geometry.
  virtual std::vector<std::pair<std::string, std::string>> infoFields(const CompressedBtf& btf) const = 0;
  // A report's method label: "clustered neural + direction planes (9 x 9 x 2), k = 1000".
  virtual std::string label(const CompressedBtf& btf) const = 0;
  // The number a sweep plots the kind against (k, C), 0 when it has none.
  virtual int sweepParameter(const CompressedBtf& btf) const = 0;
  // The kind's own invariants, after the ones every material shares (CompressedBtf::validate).
  // Throws nbtf::Error prefixed with `name`.
  virtual void validate(const CompressedBtf& btf, const std::string& name) const = 0;

  // The evaluator the decoder holds for a validated material.
  virtual std::unique_ptr<detail::MaterialEvaluator> evaluator(const CompressedBtf& btf, DecoderIsa isa,
                                                               const DecoderOptions& options) const = 0;

 private:
  CodecMethod code_;
  const char* name_;
  const char* shortName_;
};

// The registry: every kind this build knows, in code order.
const std::vector<const MethodKind*>& methodKinds();
// The kind of a stored method code; null for a code this build does not know.
const MethodKind* findMethodKind(CodecMethod code);
// The same, throwing nbtf::Error("<name>: unknown method code N") for an unknown code.
const MethodKind& methodKind(CodecMethod code, const std::string& name = "compressed BTF");

// The one kind that requires `part` (the id list: clustered; PCA's parts: PCA), named when a
// file lacks it; null when several or none do.
const MethodKind* soleKindRequiring(format::Part part);

// The own checks of every part `kind` may store (its need is not Forbidden), in the part
// table's order (format::PartRow::check): what a kind's validate runs between its own checks.
void checkStoredParts(const CompressedBtf& btf, const MethodKind& kind, const std::string& name);

// The registry's rows (one per kind file).
const MethodKind& clusteredNeuralMethod();
const MethodKind& perTexelNeuralMethod();
const MethodKind& pcaMethod();

}  // namespace nbtf
