// The registry of model kinds: one row per kind file.
#include "codec/methods/method.h"

#include "util/error.h"

namespace nbtf {

const std::vector<const MethodKind*>& methodKinds() {
  static const std::vector<const MethodKind*> kinds = {
      &clusteredNeuralMethod(),
      &perTexelNeuralMethod(),
      &pcaMethod(),
  };
  return kinds;
}

const MethodKind* findMethodKind(CodecMethod code) {
  for (const MethodKind* kind : methodKinds())
    if (kind->code() == code) return kind;
  return nullptr;
}

const MethodKind& methodKind(CodecMethod code, const std::string& name) {
  const MethodKind* kind = findMethodKind(code);
  if (!kind) throw fileError(name, "unknown method code " + std::to_string(static_cast<int>(code)));
  return *kind;
}

const MethodKind* soleKindRequiring(format::Part part) {
  const MethodKind* sole = nullptr;
  for (const MethodKind* kind : methodKinds())
    if (kind->need(part) == format::Need::Required) {
      if (sole) return nullptr;
      sole = kind;
    }
  return sole;
}

void checkStoredParts(const CompressedBtf& btf, const MethodKind& kind, const std::string& name) {
  for (const format::PartRow& row : format::partRows())
    if (row.check && kind.need(row.part) != format::Need::Forbidden) row.check(btf, name);
}

std::string codecMethodName(CodecMethod m) {
  const MethodKind* kind = findMethodKind(m);
  return kind ? kind->name() : "unknown";
}

}  // namespace nbtf
