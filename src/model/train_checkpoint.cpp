#include "model/train_checkpoint.h"

#include <cstdio>
#include <cstring>
#include <filesystem>

#include "util/byte_io.h"
#include "codec/crc32.h"

#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace {
constexpr std::int64_t kCheckpointVersion = 1;

// The file: this header, then torch's archive. A flipped byte anywhere in the archive would
// otherwise load (torch checks the zip's structure, not the tensors' bytes) and train on
// garbage until the latents turned NaN.
//   "NBTFCKPT"  8 bytes
//   crc32       4 bytes, little-endian, of the archive bytes
//   size        8 bytes, little-endian, of the archive bytes
constexpr char kMagic[8] = {'N', 'B', 'T', 'F', 'C', 'K', 'P', 'T'};
constexpr std::size_t kHeaderBytes = 8 + 4 + 8;

void writeArchive(const std::string& path, torch::serialize::OutputArchive& archive) {
  std::string payload;
  archive.save_to([&](const void* data, std::size_t size) {
    payload.append(static_cast<const char*>(data), size);
    return size;
  });
  ByteWriter file;
  file.raw(kMagic, sizeof kMagic);
  file.u32(crc32(payload.data(), payload.size()));
  file.u64(payload.size());
  file.raw(payload.data(), payload.size());
  writeFileAtomic(path, file.bytes().data(), file.bytes().size());
}

// Reads the file, checks its header and checksum, and loads the archive; a damaged or
// foreign file is refused here, by name, before any of it is used.
void readArchive(const std::string& path, torch::serialize::InputArchive& archive) {
  const std::vector<std::uint8_t> bytes = readFileBytes(path);
  const std::string advice = "; --restart deletes it and starts over";
  if (bytes.size() < kHeaderBytes || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    throw fileError(path, "is not an nbtf checkpoint (no NBTFCKPT header; an older nbtf wrote checkpoints without "
                          "checksums)" + advice);
  ByteReader header(bytes.data() + sizeof kMagic, kHeaderBytes - sizeof kMagic, path, "checkpoint header");
  const std::uint32_t stored = header.u32();
  const std::uint64_t size = header.u64();
  if (size != bytes.size() - kHeaderBytes)
    throw fileError(path, "checkpoint is damaged: its header says " + std::to_string(size) + " bytes of data, the file has " +
                              std::to_string(bytes.size() - kHeaderBytes) + advice);
  const std::uint32_t actual = crc32(bytes.data() + kHeaderBytes, size);
  if (actual != stored) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "checksum %08x, stored %08x", actual, stored);
    throw fileError(path, std::string("checkpoint is damaged (") + buf + ")" + advice);
  }
  archive.load_from(reinterpret_cast<const char*>(bytes.data() + kHeaderBytes), size);
}

std::uint64_t hashCombine(std::uint64_t h, std::uint64_t v) { return SplitMix64::mix(h, v); }
std::uint64_t hashString(std::uint64_t h, const std::string& s) {
  for (unsigned char ch : s) h = hashCombine(h, ch);
  return hashCombine(h, s.size());
}
}  // namespace

std::uint64_t checkpointFingerprint(const TrainConfig& c, const TrainingSet& set) {
  std::uint64_t h = 0x6e627466ull;  // "nbtf"
  h = hashCombine(h, c.model.latentDim);
  for (int ch : c.model.encoderChannels) h = hashCombine(h, ch);
  h = hashCombine(h, c.model.decoderWidth);
  h = hashCombine(h, c.model.decoderLayers);
  h = hashString(h, c.optimizer);
  h = hashCombine(h, c.batchSize);
  h = hashCombine(h, c.imagesPerInput);
  h = hashCombine(h, set.groups());
  h = hashCombine(h, set.images());
  h = hashCombine(h, static_cast<std::uint64_t>(set.texels()));
  for (int g = 0; g < set.groups(); ++g) h = hashCombine(h, set.groupSize(g));
  for (int i : set.holdoutImages()) h = hashCombine(h, i);
  if (set.texelCoefficientHash()) h = hashCombine(h, set.texelCoefficientHash());  // absent before modulation: old checkpoints still match
  if (c.model.directionInputs != DirectionEncoding::Stereographic)  // absent before: old checkpoints still match
    h = hashCombine(h, static_cast<std::uint64_t>(c.model.directionInputs));
  if (c.model.planeFeatures > 0)  // absent without planes: old checkpoints still match
    h = hashCombine(hashCombine(h, c.model.planeResolution), c.model.planeFeatures);
  if (c.model.clusterPlaneFeatures > 0)  // absent without cluster planes: old checkpoints still match
    h = hashCombine(hashCombine(h, 0x63706c6eull + c.model.clusterPlaneResolution), c.model.clusterPlaneFeatures);
  return h;
}

void PolishLatents::start(torch::Tensor latents, double learningRate) {
  values = latents.contiguous();
  optimizer.reset();
  if (learningRate > 0)
    optimizer = std::make_unique<torch::optim::Adam>(std::vector<torch::Tensor>{values},
                                                     torch::optim::AdamOptions(learningRate));
}

bool checkpointExists(const std::string& path) {
  std::error_code ec;
  return !path.empty() && std::filesystem::is_regular_file(path, ec);
}

void saveCheckpoint(const std::string& path, const CheckpointMeta& meta, torch::nn::Module& encoder,
                    torch::nn::Module& decoder, torch::optim::Optimizer& optimizer, const PolishLatents& polish) {
  torch::serialize::OutputArchive archive, enc, dec, opt;
  archive.write("version", torch::tensor(kCheckpointVersion));
  archive.write("step", torch::tensor(meta.step));
  archive.write("elapsed_seconds", torch::tensor(meta.elapsedSeconds, torch::kDouble));
  archive.write("ema_loss", torch::tensor(meta.emaLoss, torch::kDouble));
  archive.write("total_steps", torch::tensor(meta.totalSteps));
  // The fingerprint is 64 bits; store it as the signed value with the same bits.
  archive.write("fingerprint", torch::tensor(static_cast<std::int64_t>(meta.fingerprint)));
  encoder.save(enc);
  decoder.save(dec);
  optimizer.save(opt);
  archive.write("encoder", enc);
  archive.write("decoder", dec);
  archive.write("optimizer", opt);
  if (polish.free()) {
    torch::serialize::OutputArchive latentOpt;
    polish.optimizer->save(latentOpt);
    archive.write("polish_latents", polish.values);
    archive.write("polish_optimizer", latentOpt);
  }
  writeArchive(path, archive);
}

namespace {

// The run's position (version checked, step, time, loss, planned steps, fingerprint) from an
// archive readArchive accepted. A fresh tensor per value: read() into a defined tensor calls
// set_(), which keeps that tensor's dtype and reinterprets the stored bytes (the double
// elapsed_seconds read into the int64 tensor of the step came back as 4.6e18 s, so a resumed
// --time-budget run found its budget spent and did no training).
CheckpointMeta readMeta(torch::serialize::InputArchive& archive, const std::string& path) {
  auto value = [&](const char* key) {
    torch::Tensor t;
    archive.read(key, t);
    return t;
  };
  const std::int64_t version = value("version").item<std::int64_t>();
  if (version != kCheckpointVersion)
    throw fileError(path, "checkpoint version " + std::to_string(version) + ", this nbtf reads " +
                              std::to_string(kCheckpointVersion) + "; --restart deletes it and starts over");
  CheckpointMeta meta;
  meta.fingerprint = static_cast<std::uint64_t>(value("fingerprint").item<std::int64_t>());
  meta.step = value("step").item<std::int64_t>();
  meta.elapsedSeconds = value("elapsed_seconds").item<double>();
  meta.emaLoss = value("ema_loss").item<double>();
  meta.totalSteps = value("total_steps").item<std::int64_t>();
  return meta;
}

// Runs `read`; torch reports corrupt or foreign files as c10::Error with a long backtrace:
// keep its first line, under the file's name.
template <class Read>
auto readingCheckpoint(const std::string& path, Read read) {
  try {
    return read();
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    std::string what = e.what();
    throw fileError(path, "cannot read checkpoint: " + what.substr(0, what.find('\n')) +
                              "; --restart deletes it and starts over");
  }
}

}  // namespace

CheckpointMeta loadCheckpoint(const std::string& path, std::uint64_t expectedFingerprint, torch::nn::Module& encoder,
                              torch::nn::Module& decoder, torch::optim::Optimizer& optimizer, PolishLatents& polish,
                              double latentLearningRate, bool checkFingerprint) {
  return readingCheckpoint(path, [&] {
    torch::serialize::InputArchive archive, enc, dec, opt;
    readArchive(path, archive);
    const CheckpointMeta meta = readMeta(archive, path);
    if (checkFingerprint && meta.fingerprint != expectedFingerprint)
      throw fileError(path,
                      "checkpoint is from a different setup (data, clusters, hold-out, model, optimizer or batch "
                      "geometry differ); remove it or rerun with the same inputs and config");
    archive.read("encoder", enc);
    archive.read("decoder", dec);
    archive.read("optimizer", opt);
    encoder.load(enc);
    decoder.load(dec);
    optimizer.load(opt);
    torch::Tensor latents;
    if (checkFingerprint && archive.try_read("polish_latents", latents)) {
      polish.start(latents, latentLearningRate);
      torch::serialize::InputArchive latentOpt;
      if (polish.free() && archive.try_read("polish_optimizer", latentOpt)) polish.optimizer->load(latentOpt);
    }
    return meta;
  });
}

CheckpointSummary readCheckpointSummary(const std::string& path) {
  return readingCheckpoint(path, [&] {
    torch::serialize::InputArchive archive;
    readArchive(path, archive);
    const CheckpointMeta meta = readMeta(archive, path);
    CheckpointSummary summary;
    summary.step = meta.step;
    summary.totalSteps = meta.totalSteps;
    summary.elapsedSeconds = meta.elapsedSeconds;
    return summary;
  });
}

namespace {
std::vector<double> asDoubles(const torch::Tensor& t) {
  torch::Tensor d = t.to(torch::kCPU).to(torch::kDouble).contiguous();
  return std::vector<double>(d.data_ptr<double>(), d.data_ptr<double>() + d.numel());
}

// Every tensor of an archive, depth first, keys joined with '/'.
void collectTensors(torch::serialize::InputArchive& archive, const std::string& prefix,
                    std::vector<std::pair<std::string, std::vector<double>>>& out) {
  for (const std::string& key : archive.keys()) {
    torch::Tensor t;
    if (archive.try_read(key, t)) {
      out.emplace_back(prefix + key, asDoubles(t));
      continue;
    }
    torch::serialize::InputArchive sub;
    if (archive.try_read(key, sub)) collectTensors(sub, prefix + key + "/", out);
  }
}
}  // namespace

CheckpointState readCheckpointState(const std::string& path) {
  CheckpointState state;
  try {
    torch::serialize::InputArchive archive;
    readArchive(path, archive);
    torch::Tensor t;
    archive.read("step", t);
    state.step = t.item<std::int64_t>();
    torch::Tensor f;
    archive.read("fingerprint", f);
    state.fingerprint = static_cast<std::uint64_t>(f.item<std::int64_t>());
    for (const char* part : {"encoder", "decoder"}) {
      torch::serialize::InputArchive sub;
      archive.read(part, sub);
      collectTensors(sub, std::string(part) + "/", state.tensors);
    }
    torch::Tensor latents;
    if (archive.try_read("polish_latents", latents)) state.tensors.emplace_back("polish_latents", asDoubles(latents));
    // The optimizer's state is keyed by each parameter's address in the process that wrote
    // it: name it by the parameter's position in the param groups instead.
    torch::serialize::InputArchive opt, perParam, groupList;
    archive.read("optimizer", opt);
    opt.read("param_groups", groupList);
    torch::Tensor groups;
    groupList.read("param_groups/size", groups);
    std::vector<std::string> order;
    for (std::int64_t g = 0; g < groups.item<std::int64_t>(); ++g) {
      torch::serialize::InputArchive group;
      groupList.read("param_groups/" + std::to_string(g), group);
      torch::Tensor size;
      group.read("params/size", size);
      for (std::int64_t i = 0; i < size.item<std::int64_t>(); ++i) {
        c10::IValue key;
        group.read("params/" + std::to_string(i), key);
        order.push_back(key.toStringRef());
      }
    }
    opt.read("state", perParam);
    for (std::size_t i = 0; i < order.size(); ++i) {
      torch::serialize::InputArchive one;
      if (!perParam.try_read(order[i], one)) continue;  // no step taken for this parameter yet
      char name[32];
      std::snprintf(name, sizeof name, "param%04zu", i);
      const std::string prefix = std::string("optimizer/") + name + "/";
      collectTensors(one, prefix, state.tensors);
      c10::IValue step;
      if (one.try_read("step", step) && (step.isInt() || step.isDouble()))
        state.tensors.emplace_back(prefix + "step", std::vector<double>{step.isInt() ? static_cast<double>(step.toInt())
                                                                                   : step.toDouble()});
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    std::string what = e.what();
    throw fileError(path, "cannot read checkpoint: " + what.substr(0, what.find('\n')));
  }
  return state;
}

}  // namespace nbtf
