// libFuzzer target for the .nbtf reader: everything a hostile file can reach when a user
// runs `nbtf info`, `nbtf decode` or opens it with NbtfDecoder (docs/reliability.md).
//
// Each input is parsed twice: once as a user's file is (checksums verified, which almost
// every mutation fails), and once with the checksums off, so mutated sizes, offsets, counts
// and values reach the structural checks behind them. Whatever parses is then described
// (`nbtf info`'s text, which reads the metadata JSON), opened as a decoder (weight packing,
// first-layer cache) and evaluated, because a file that passes validation must also be
// safe to decode.
//
// The reader's contract: bad input throws nbtf::Error. Any other exception, a crash, a leak
// or a sanitizer report is a bug; libFuzzer stops and saves the input. Built and run by
// scripts/fuzz.sh (ASan + UBSan + leak detection).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "codec/decoder.h"
#include "codec/nbtf_describe.h"
#include "codec/nbtf_file.h"
#include "util/error.h"

namespace {

void exerciseDecoder(nbtf::CompressedBtf material) {
  const nbtf::Direction light = material.lights.front(), view = material.views.back();
  nbtf::DecoderOptions options;
  // Portable kernels: the same code on every machine, so a saved crash replays anywhere.
  options.isa = nbtf::DecoderIsa::Portable;
  nbtf::NbtfDecoder decoder(std::move(material), options, "fuzz.nbtf");

  std::vector<float> rows(3 * static_cast<std::size_t>(decoder.latentRows()));
  decoder.decodeRows(light, view, rows.data());
  std::vector<float> image(3 * static_cast<std::size_t>(decoder.numTexels()));
  decoder.decodeImage(light, view, image.data(), nbtf::OutputScale::Normalized);
  decoder.evaluate(decoder.width() - 1, decoder.height() - 1, light, view);
  decoder.evaluateUv(0.5f, 0.25f, {10, 20}, {45, 300});
  // An unmeasured direction below the horizon must be refused, never evaluated.
  try {
    decoder.evaluate(0, 0, {95, 0}, view);
  } catch (const nbtf::Error&) {
  }
}

void parseAndUse(const std::uint8_t* data, std::size_t size, bool verifyChecksums) {
  nbtf::NbtfParseOptions options;
  options.verifyChecksums = verifyChecksums;
  nbtf::CompressedBtf material;
  try {
    material = nbtf::parseNbtf(data, size, "fuzz.nbtf", options);
  } catch (const nbtf::Error&) {
    return;  // refused with a message: what the reader must do with bad input
  }
  (void)nbtf::describeNbtf(material, "fuzz.nbtf", size);
  // A parsed file is valid, so serializing it again must succeed and read back.
  std::vector<std::uint8_t> again = nbtf::serializeNbtf(material);
  (void)nbtf::parseNbtf(again.data(), again.size(), "fuzz.nbtf (rewritten)");
  exerciseDecoder(std::move(material));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  parseAndUse(data, size, /*verifyChecksums=*/true);
  parseAndUse(data, size, /*verifyChecksums=*/false);
  return 0;
}
