// The compressed material, `.nbtf`: one self-describing, checksummed binary file holding
// everything decoding needs (decoder MLP, latents, texel -> latent id list, directions,
// geometry, alpha; or, for the PCA baseline, mean, basis and coefficients) plus provenance
// (hold-out images, metadata JSON, optionally the encoder). Byte layout and versioning rules: docs/file_format.md.
//
// The reader treats the file as untrusted input: parseNbtf() validates every size and
// offset before use, never allocates more than the bytes present justify, and reports
// each kind of damage (truncated, corrupted, wrong magic, newer version, inconsistent
// content) as an nbtf::Error naming the file and what is wrong.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "util/layout.h"
#include "util/direction_planes.h"
#include "util/directions.h"
#include "codec/mlp.h"

namespace nbtf {

// Format version read by this build. A reader accepts any minor version of its major
// (minor versions only add optional sections, append fields, or add content whose files carry
// required sections or codes an older reader refuses by name); a newer major is refused. The
// writer writes the lowest version that describes the file: the highest version among the
// sections it writes (the section table, codec/nbtf_sections.h; docs/file_format.md).
constexpr std::uint16_t kNbtfFormatMajor = 1;
constexpr std::uint16_t kNbtfFormatMinor = 11;
// "\x89NBTF\r\n\x1a": the high byte catches 7-bit transfers, CR LF catches newline
// conversion, 0x1A stops `type` on DOS-like systems (the PNG idea).
constexpr unsigned char kNbtfMagic[8] = {0x89, 'N', 'B', 'T', 'F', 0x0D, 0x0A, 0x1A};

// How the material is represented: the model kind, one component each (codec/methods/method.h).
// Values are stored in the file; never renumber.
enum class CodecMethod : std::uint8_t {
  ClusteredNeural = 1,  // one latent per cluster + id list (the paper's method)
  PerTexelNeural = 2,   // one latent per texel (the earlier neural BTF; our baseline)
  Pca = 3,              // classic PCA baseline: mean + coefficients x basis (format 1.1)
};
std::string codecMethodName(CodecMethod m);  // "clustered-neural", "per-texel-neural", "pca"

// What the decoder outputs: linear sRGB-primaries RGB divided by alpha (eq. 5).
enum class ValueSpace : std::uint8_t { LinearOverAlpha = 1 };

// Per-texel modulation (format 1.2, codec/texel_modulation.h): the decoder outputs `terms`
// RGB terms per latent row and every texel mixes them with coefficients of its own, stored as
// `bits`-bit linear codes over [minimum, maximum] of their term: a = minimum + code / (2^bits
// - 1) x (maximum - minimum). Decoders orthonormalize the coefficients per cluster; empty
// (terms 0) = no modulation (the decoder outputs one RGB term).
// Format 1.5 (section TXCH): `channels` 3 gives every texel one coefficient per term and RGB
// channel (a colour factor with one term) instead of one per term for all three.
// Format 1.11 (section TXCR, channels 3 only): decorrelated codes. Each term's three columns
// hold the colour factor in its principal axes over the texels, coded at one common step, and
// channel c of term r decodes as sum_k rotation[9r + 3c + k] x a_{r,k} (a the column values
// above). Correlated channels then cost fewer bytes at the same error.
constexpr int kMaxModulationTerms = 8;
struct TexelModulation {
  int terms = 0;     // 0 = none, else 1..kMaxModulationTerms
  int channels = 1;  // coefficients per term: 1 (shared by RGB) or 3 (one per channel)
  int bits = 0;      // 1..16
  // Per column (term r, channel c at r x channels + c).
  std::array<float, 3 * kMaxModulationTerms> minimum{}, maximum{};
  std::vector<std::uint16_t> codes;  // texels x columns, texel-major
  bool decorrelated = false;         // format 1.11: the columns are rotated (channels 3)
  std::array<float, 9 * kMaxModulationTerms> rotation{};  // per term, row-major 3 x 3, orthonormal
  bool empty() const { return terms == 0; }
  int columns() const { return terms * channels; }
};

// How the decoding parts are stored (format 1.2). Half floats are IEEE binary16: the values
// in memory are then exactly the stored ones (roundToStorage rounds them before writing).
struct PartStorage {
  bool decoderHalf = false;     // DECH instead of DECD
  bool decoderInt8 = false;     // DEC8 (format 1.4): 8-bit weights, a half scale per output row, half biases
  bool latentsHalf = false;     // LATH instead of LATN
  bool idsZstd = false;         // TXIZ (zstd over byte planes) instead of TXID
  bool modulationZstd = true;   // TXSC codes zstd-coded
  bool metadataZstd = false;    // METZ and HOLZ (zstd-coded, format 1.4) instead of META and HOLD
  bool directionsZstd = false;  // DIRZ (byte planes, zstd-coded, format 1.4) instead of DIRS
  bool clusterPlanes8Bit = false;  // CPLN value type 2 (format 1.10): 8-bit codes in per-row, per-feature ranges
  // Whether storing changes decoded values (roundToStorage): the measured RMSE is then the file's.
  bool anyRounding() const { return decoderHalf || decoderInt8 || latentsHalf || clusterPlanes8Bit; }
  // Any part stored otherwise than in format 1.0 (the paper's float32 parts, raw ids).
  bool anyCompact() const {
    return decoderHalf || decoderInt8 || latentsHalf || idsZstd || metadataZstd || directionsZstd || clusterPlanes8Bit;
  }
};

struct CompressedBtf {
  CodecMethod method = CodecMethod::ClusteredNeural;
  DirectionEncoding directionEncoding = DirectionEncoding::Stereographic;
  ValueSpace valueSpace = ValueSpace::LinearOverAlpha;

  // ---- The material's geometry and sampling
  int width = 0, height = 0;              // texels (after the crop)
  int sourceWidth = 0, sourceHeight = 0;  // image size on disk
  Crop crop;                              // empty = whole image
  Layout layout = Layout::Unknown;        // layout of the source stack (decode writes the same)
  SampleType sourceSampleType = SampleType::Srgb8;
  std::vector<Direction> lights, views;   // measured directions; image = light * views + view
  float alpha = 1;                        // decoder output * alpha = linear value

  // ---- The representation
  Mlp decoder;                            // input: latent, the direction inputs of directionEncoding, the planes' features; output RGB; empty for PCA
  // Learned direction planes (format 1.8; util/direction_planes.h): their 3 F features follow
  // the fixed direction inputs. Stored as float32 with a float32 decoder, in half otherwise.
  DirectionPlanes planes;
  // Each latent row's own direction planes (format 1.9, section CPLN; util/direction_planes.h):
  // their 3 F features follow the shared planes'. Stored like the direction planes, or in 8 bits.
  RowPlanes clusterPlanes;
  int latentDim = 8;                      // PCA: the number of components C
  int latentRows = 0;                     // k (clustered) or texels (per-texel, PCA)
  std::vector<float> latents;             // latentRows x latentDim, row-major; PCA: the coefficients
  std::vector<std::int32_t> ids;          // texel -> latent row; empty in per-texel mode and PCA
  // PCA baseline only (codec/pca_model.h): value(t, image, c) = pcaMean[3 image + c] +
  // latents(t) . basis row 3 image + c, in linear RGB / alpha.
  std::vector<float> pcaMean;             // 3 x images (image-major, RGB)
  std::vector<float> pcaBasis;            // (3 x images) rows x C, row-major (one row per image channel)
  TexelModulation modulation;             // clustered only; empty = every texel of a cluster decodes alike
  PartStorage storage;                    // how the parts above are written

  // ---- Provenance (not needed to decode)
  std::vector<int> holdoutImages;         // ascending image indices kept out of training
  std::vector<std::uint8_t> encoderState; // serialized encoder; empty unless --save-encoder
  std::string metadataJson = "{}";        // config, seed, training statistics (a JSON object)

  // Filled by parseNbtf only: the file's format version and the optional sections this
  // reader did not know (skipped). The writer picks the version (see kNbtfFormatMinor).
  std::uint16_t formatMajor = kNbtfFormatMajor, formatMinor = kNbtfFormatMinor;
  std::vector<std::string> skippedSections;

  // The decoder's direction inputs: the encoding's, then the planes', then the cluster planes'.
  int directionInputs() const {
    return directionInputCount(directionEncoding) + planes.inputCount() + clusterPlanes.inputCount();
  }
  int numImages() const { return static_cast<int>(lights.size() * views.size()); }
  int numTexels() const { return width * height; }
  int numClusters() const { return method == CodecMethod::ClusteredNeural ? latentRows : 0; }
  bool isPca() const { return method == CodecMethod::Pca; }
  int pcaComponents() const { return isPca() ? latentDim : 0; }
  // The latent row texel t decodes from.
  int latentRowOfTexel(int texel) const { return ids.empty() ? texel : ids[static_cast<std::size_t>(texel)]; }
  const float* latentOfTexel(int texel) const {
    return latents.data() + static_cast<std::size_t>(latentRowOfTexel(texel)) * latentDim;
  }

  // Checks every invariant the reader checks (shapes agree, values finite, ids in range,
  // directions on the hemisphere...). Throws nbtf::Error prefixed with `name`.
  void validate(const std::string& name = "compressed BTF") const;
};

// Rounds the decoder and latents to half precision where `storage` says so, so that what is
// in memory (and measured) is exactly what the file will hold.
void roundToStorage(CompressedBtf& btf);

// "decoder int8, latents half, ids zstd, directions zstd, metadata zstd": how the parts are stored, for info
// and reports.
std::string storageDescription(const CompressedBtf& btf);

// Smallest unsigned integer width (1, 2 or 4 bytes) that holds every id in [0, k).
int idWidthForClusters(std::int64_t k);

// Sizes in bytes as in Table 1 of the paper, as stored: decoder = parameters x 4 (float32)
// or x 2 (half), latents = rows x latentDim x 4 or 2, ids = texels x id width (the paper used
// 4-byte ids; we store the smallest width that fits k) or the zstd-coded bytes, modulation =
// the per-texel factors' stored bytes, planes = the direction planes' values as stored,
// total = decoder + planes + latents + ids + modulation (the
// paper's definition: headers, directions and metadata are not counted; fileBytes is the
// actual file size), raw = texels x images x 3 x 4 (float32 RGB), ratio = raw / total.
// PCA: decoder, latents and ids are 0; total = mean + basis + coefficients (float32 each).
struct NbtfSizes {
  std::uint64_t decoderParameters = 0;
  std::uint64_t latentRows = 0, texels = 0, images = 0;
  int latentDim = 0;
  std::uint64_t decoder = 0, latents = 0, ids = 0, modulation = 0, total = 0;
  std::uint64_t planes = 0;  // direction planes: 3 x R x R x F values x 2 (half) or 4 (float32)
  int planeResolution = 0, planeFeatures = 0, planeBytesPerValue = 0;
  std::uint64_t clusterPlanes = 0;  // cluster planes: rows x 3 x R x R x F values, as the planes
  int clusterPlaneResolution = 0, clusterPlaneFeatures = 0, clusterPlaneBytesPerValue = 0;  // 1: 8-bit codes
  int decoderBytesPerValue = 4, latentBytesPerValue = 4;  // decoder: 1 = 8-bit weights (DEC8)
  bool idsZstd = false;
  int modulationTerms = 0, modulationChannels = 1, modulationBits = 0;
  bool modulationDecorrelated = false;  // TXCR (format 1.11)
  std::uint64_t rawFloat32 = 0;
  std::uint64_t fileBytes = 0;  // 0 when not known (not written yet)
  int idWidth = 0;              // bytes per id; 0 in per-texel mode
  double ratio = 0;             // rawFloat32 / total
  // The same with the paper's 4-byte ids, to compare with its Table 1.
  std::uint64_t idsPaper = 0, totalPaper = 0;
  double ratioPaper = 0;
  // PCA baseline: components C; mean 3N x 4, basis 3N x C x 4, coefficients texels x C x 4.
  bool pca = false;
  int pcaComponents = 0;
  std::uint64_t pcaMean = 0, pcaBasis = 0, pcaCoefficients = 0;
  // The size table's rows: each stored part (and a part the kind shows as absent, at 0 bytes)
  // with what its bytes are made of, in the part table's order (codec/nbtf_sections.h).
  struct PartRow {
    std::string name, totalName, note;
    std::uint64_t bytes = 0;
  };
  std::vector<PartRow> rows;
};
NbtfSizes computeSizes(const CompressedBtf& btf, std::uint64_t fileBytes = 0);

// The Table-1-style size table as text lines (shared by `nbtf info` and `nbtf compress`).
std::string formatSizeTable(const NbtfSizes& sizes);

// ---- Reading and writing

// Serializes to bytes (validates first). Deterministic: same content -> same bytes.
std::vector<std::uint8_t> serializeNbtf(const CompressedBtf& btf);
// Writes atomically (temporary file + rename). Returns the number of bytes written.
std::size_t writeNbtf(const std::string& path, const CompressedBtf& btf);

struct NbtfParseOptions {
  // Verify the header and body CRC-32s. Only the fuzzer turns this off, so that mutated
  // inputs reach the structural checks behind the checksum.
  bool verifyChecksums = true;
};
// Parses a complete file image. `name` is used in error messages (normally the path).
CompressedBtf parseNbtf(const std::uint8_t* data, std::size_t size, const std::string& name,
                        const NbtfParseOptions& options = {});
CompressedBtf readNbtf(const std::string& path);

// True when the file starts with the .nbtf magic (false for folders and unreadable paths).
bool hasNbtfMagic(const std::string& path);

}  // namespace nbtf
