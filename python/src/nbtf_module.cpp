// _nbtf: the torch-free half of the Python module `nbtf` (python/nbtf/__init__.py wraps it):
// a .nbtf material (the decoder of codec/decoder.h) and the image stack loader (io/). Arrays
// arrive checked and flattened by __init__.py (dtype, shape, broadcasting); every value is
// checked here by the library, whose nbtf::Error becomes ValueError (OSError for files).
// Decoding runs with the GIL released, on the library's threads (threadCount()).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "codec/decoder.h"
#include "codec/nbtf_file.h"
#include "codec/nbtf_info.h"
#include "common.h"
#include "io/btf_loader.h"
#include "io/image_io.h"
#include "util/atomic_file.h"
#include "util/layout.h"
#include "util/memory.h"
#include "util/parallel.h"

namespace nbtf::python {
namespace {

using FloatArray = py::array_t<float, py::array::c_style>;
using DoubleArray = py::array_t<double, py::array::c_style>;
using IntArray = py::array_t<std::int32_t, py::array::c_style>;

// n x k C-contiguous arrays of the dtype asked for (__init__.py converts; this checks).
template <class T>
std::size_t rows(const py::array_t<T, py::array::c_style>& a, int k, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != k)
    throw Error(std::string(what) + ": expected an array of shape (n, " + std::to_string(k) + ")");
  return static_cast<std::size_t>(a.shape(0));
}

FloatArray rgbArray(std::size_t n) { return FloatArray({static_cast<py::ssize_t>(n), py::ssize_t(3)}); }

Direction directionOf(const std::vector<double>& d, const char* what) {
  if (d.size() == 2) return Direction{d[0], d[1]};
  if (d.size() == 3) {
    const auto u = unitQueryVector({static_cast<float>(d[0]), static_cast<float>(d[1]), static_cast<float>(d[2])}, what);
    return Direction::fromUnitVector(u[0], u[1], u[2]);
  }
  throw Error(std::string(what) + ": expected (theta, phi) in degrees or a unit vector (x, y, z), got " +
              std::to_string(d.size()) + " values");
}

py::array_t<double> directionsArray(const std::vector<Direction>& dirs) {
  py::array_t<double> a({static_cast<py::ssize_t>(dirs.size()), py::ssize_t(2)});
  auto m = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < dirs.size(); ++i) m(i, 0) = dirs[i].thetaDeg, m(i, 1) = dirs[i].phiDeg;
  return a;
}

// An open .nbtf file. The decoder is shared with calls in flight, so close() never pulls it
// from under a decode running on another Python thread.
class Material {
 public:
  Material(const std::string& path, const std::string& isa) : path_(path) {
    DecoderOptions options;
    options.isa = parseDecoderIsa(isa);
    std::vector<std::uint8_t> bytes;
    {
      py::gil_scoped_release release;
      bytes = readFileBytes(path);
      CompressedBtf btf = parseNbtf(bytes.data(), bytes.size(), path);
      fileBytes_ = bytes.size();
      infoJson_ = nbtfInfoJson(btf, path, fileBytes_);
      sizes_ = computeSizes(btf, fileBytes_);
      decoder_ = std::make_shared<const NbtfDecoder>(std::move(btf), options, path);
    }
  }

  std::shared_ptr<const NbtfDecoder> decoder() const {
    if (!decoder_) throw Error(path_ + ": the material is closed");
    return decoder_;
  }
  void close() { decoder_.reset(); }
  bool closed() const { return !decoder_; }
  const std::string& path() const { return path_; }
  const std::string& infoJson() const { return infoJson_; }

  // nbtfPartBytes (codec/nbtf_info.h): the parts `nbtf info --json` lists under "bytes".
  py::dict sizes() const { return py::module_::import("json").attr("loads")(nbtfPartBytes(sizes_).dump()); }

  // Runs f(i) for every query; an error names the query when there are several.
  template <typename F>
  static void forEachQuery(std::size_t n, F f) {
    for (std::size_t i = 0; i < n; ++i) {
      try {
        f(i);
      } catch (const Error& e) {
        throw Error(n == 1 ? std::string(e.what()) : "query " + std::to_string(i) + ": " + e.what());
      }
    }
  }

  // The batch, decoded with the GIL released (TexelQuery or UvQuery).
  template <typename Query>
  static FloatArray evaluateWithoutGil(const NbtfDecoder& dec, const std::vector<Query>& queries, bool normalized) {
    const std::size_t n = queries.size();
    FloatArray out = rgbArray(n);
    float* rgb = out.mutable_data();
    const OutputScale scale = normalized ? OutputScale::Normalized : OutputScale::Linear;
    {
      py::gil_scoped_release release;
      dec.evaluate(queries.data(), n, rgb, scale);
    }
    return out;
  }

  // Texels (x, y) or texture coordinates (u, v), angles in degrees: the path of `nbtf query`
  // (its single queries and --batch alike: the batch equals the single evaluations bit for bit).
  FloatArray queryAngles(std::optional<IntArray> texels, std::optional<FloatArray> uvs, const DoubleArray& light,
                         const DoubleArray& view, bool normalized) const {
    auto dec = decoder();
    const std::size_t n = rows(light, 2, "light");
    if (rows(view, 2, "view") != n) throw Error("light and view: different numbers of queries");
    std::vector<TexelQuery> queries(n);
    const double* l = light.data();
    const double* v = view.data();
    for (std::size_t i = 0; i < n; ++i) {
      queries[i].light = {l[2 * i], l[2 * i + 1]};
      queries[i].view = {v[2 * i], v[2 * i + 1]};
    }
    if (texels) {
      if (rows(*texels, 2, "texel") != n) throw Error("texel: a different number of queries than light and view");
      const std::int32_t* t = texels->data();
      for (std::size_t i = 0; i < n; ++i) queries[i].x = t[2 * i], queries[i].y = t[2 * i + 1];
    } else {
      if (rows(*uvs, 2, "uv") != n) throw Error("uv: a different number of queries than light and view");
      const float* uv = uvs->data();
      forEachQuery(n, [&](std::size_t i) {
        const int texel = dec->texelOfUv(uv[2 * i], uv[2 * i + 1]);
        queries[i].x = texel % dec->width(), queries[i].y = texel / dec->width();
      });
    }
    return evaluateWithoutGil(*dec, queries, normalized);
  }

  // Texels or texture coordinates with unit vectors in the local frame (z = the normal): the
  // decoder's UvQuery path (a texel (x, y) is the coordinate of its centre).
  FloatArray queryVectors(std::optional<IntArray> texels, std::optional<FloatArray> uvs, const FloatArray& light,
                          const FloatArray& view, bool normalized) const {
    auto dec = decoder();
    const std::size_t n = rows(light, 3, "light");
    if (rows(view, 3, "view") != n) throw Error("light and view: different numbers of queries");
    std::vector<UvQuery> queries(n);
    const float* l = light.data();
    const float* v = view.data();
    for (std::size_t i = 0; i < n; ++i) {
      queries[i].light = {l[3 * i], l[3 * i + 1], l[3 * i + 2]};
      queries[i].view = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
    }
    if (texels) {
      if (rows(*texels, 2, "texel") != n) throw Error("texel: a different number of queries than light and view");
      const std::int32_t* t = texels->data();
      forEachQuery(n, [&](std::size_t i) {
        dec->checkTexel(t[2 * i], t[2 * i + 1]);
        queries[i].u = static_cast<float>((t[2 * i] + 0.5) / dec->width());
        queries[i].v = static_cast<float>((t[2 * i + 1] + 0.5) / dec->height());
      });
    } else {
      if (rows(*uvs, 2, "uv") != n) throw Error("uv: a different number of queries than light and view");
      const float* uv = uvs->data();
      for (std::size_t i = 0; i < n; ++i) queries[i].u = uv[2 * i], queries[i].v = uv[2 * i + 1];
    }
    return evaluateWithoutGil(*dec, queries, normalized);
  }

  FloatArray decodeImage(const std::vector<double>& light, const std::vector<double>& view, int width, int height,
                         bool normalized) const {
    auto dec = decoder();
    const Direction l = directionOf(light, "light"), v = directionOf(view, "view");
    checkHemisphere(l, "light");
    checkHemisphere(v, "view");
    if (width == 0) width = dec->width();
    if (height == 0) height = dec->height();
    if (width < 1 || height < 1 || width > (1 << 16) || height > (1 << 16))
      throw Error("size: expected (width, height), each in 1.." + std::to_string(1 << 16) + ", got (" +
                  std::to_string(width) + ", " + std::to_string(height) + ")");
    FloatArray out({py::ssize_t(height), py::ssize_t(width), py::ssize_t(3)});
    float* rgb = out.mutable_data();
    const OutputScale scale = normalized ? OutputScale::Normalized : OutputScale::Linear;
    {
      py::gil_scoped_release release;
      dec->decodeImage(l, v, rgb, scale, width, height, /*parallel=*/true);
    }
    return out;
  }

 private:
  std::string path_;
  std::shared_ptr<const NbtfDecoder> decoder_;
  std::uint64_t fileBytes_ = 0;
  std::string infoJson_;
  NbtfSizes sizes_;
};

std::string describeShape(const StackShape& shape) {
  return std::to_string(shape.width) + " x " + std::to_string(shape.height) + " texels x " +
         std::to_string(shape.images()) + " images (" +
         (shape.computedBytes ? "computed from UBO2014 factors"
                              : shape.type == SampleType::Srgb8 ? "8-bit" : "half float") +
         ")";
}

// A loaded stack, kept alive by the arrays that view its storage.
py::dict loadStack(const std::string& path, const std::string& crop, const std::string& layout, bool linear,
                   const std::string& memoryLimit, py::object progress, bool quiet) {
  LoadOptions options;
  if (!crop.empty()) options.crop = parseCrop(crop);
  if (!layout.empty()) options.layout = parseLayout(layout);
  const std::size_t limit = memoryLimit.empty() ? defaultMemoryLimit() : parseByteSize(memoryLimit, "memory_limit");
  const std::string limitText = memoryLimit.empty()
                                    ? "the default memory_limit (75% of the " + formatBytes(physicalMemoryBytes()) +
                                          " of physical memory)"
                                    : "memory_limit " + memoryLimit;
  // Refused before loading, as `nbtf compress` refuses what cannot fit: the stack as it is
  // kept, plus the float32 copy linear=True returns.
  // A UBO2014 file is expanded into half floats when that takes at most half the limit, else
  // kept factorized (its values computed when read), as `nbtf compress` and `nbtf cluster` do.
  options.expandUpTo = limit / 2;
  std::unique_ptr<BtfStack> stack;
  ProgressScope scope(progress, quiet);
  {
    py::gil_scoped_release release;
    const BtfInput input = resolveBtfInput(path, options);
    const StackShape& shape = input.shape;
    const std::size_t values = static_cast<std::size_t>(shape.images()) * static_cast<std::size_t>(shape.texels()) * 3;
    const std::size_t need = shape.stackBytes() + (linear ? values * sizeof(float) : 0);
    if (need > limit)
      throw fileError(path, describeShape(shape) + " need about " + formatBytes(need) + " of memory (the stack " +
                                formatBytes(shape.stackBytes()) +
                                (linear ? " + " + formatBytes(values * sizeof(float)) + " as float32" : std::string()) +
                                "); " + limitText + " allows " + formatBytes(limit) +
                                ". Load a part of it (crop=(x, y, w, h)) or raise memory_limit");
    options.progress = true;
    stack = std::make_unique<BtfStack>(loadBtfStack(input, options));
  }
  scope.rethrow();
  const BtfStack& s = *stack;
  const py::ssize_t images = s.numImages(), h = s.height(), w = s.width();
  py::dict d;
  d["lights"] = directionsArray(s.lights());
  d["views"] = directionsArray(s.views());
  d["layout"] = layoutName(s.layout);
  d["samples"] = sampleTypeName(s.sampleType());
  d["source"] = s.source;
  d["image_size"] = py::make_tuple(s.sourceWidth, s.sourceHeight);
  d["crop"] = s.crop.empty() ? py::object(py::none()) : py::object(py::make_tuple(s.crop.x, s.crop.y, s.crop.width, s.crop.height));
  d["computed"] = s.isComputed();
  if (linear) {
    FloatArray out({images, h, w, py::ssize_t(3)});
    float* data = out.mutable_data();
    const std::size_t perImage = static_cast<std::size_t>(h) * w * 3;
    {
      py::gil_scoped_release release;
      parallelForDynamic(images, [&](std::size_t i, int) { s.imageLinear(static_cast<int>(i), data + i * perImage); });
    }
    d["images"] = out;
    return d;
  }
  if (s.isComputed())
    throw Error(path + ": " + describeShape(StackShape{s.numLights(), s.numViews(), s.width(), s.height(), s.sampleType(), s.bytesInMemory()}) +
                " is kept as its factors, its values computed when read: it has no stored samples (linear=True gives them)");
  // The stored samples, without a copy: 8-bit sRGB codes or half floats.
  const BtfStack* raw = stack.release();
  py::capsule owner(raw, [](void* p) { delete static_cast<BtfStack*>(p); });
  const bool eight = raw->sampleType() == SampleType::Srgb8;
  const py::dtype dtype = eight ? py::dtype::of<std::uint8_t>() : py::dtype("float16");
  const py::ssize_t item = eight ? 1 : 2;
  py::array a(dtype, {images, h, w, py::ssize_t(3)}, {h * w * 3 * item, w * 3 * item, 3 * item, item},
              images ? raw->imageBytes(0) : nullptr, owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  d["images"] = a;
  return d;
}

FloatArray readImageLinear(const std::string& path) {
  ImageF image;
  {
    py::gil_scoped_release release;
    image = readExr(path);
  }
  FloatArray out({py::ssize_t(image.height), py::ssize_t(image.width), py::ssize_t(3)});
  std::memcpy(out.mutable_data(), image.rgb.data(), image.rgb.size() * sizeof(float));
  return out;
}

}  // namespace
}  // namespace nbtf::python

PYBIND11_MODULE(_nbtf, m) {
  using namespace nbtf;
  using namespace nbtf::python;
  m.doc() = "nbtf's decoder and stack loader (no libtorch); use the package `nbtf`";
  m.attr("__version__") = NBTF_VERSION;
  registerErrors();

  py::class_<Material>(m, "Material")
      .def(py::init<const std::string&, const std::string&>(), py::arg("path"), py::arg("isa") = "auto")
      .def("close", &Material::close)
      .def_property_readonly("closed", &Material::closed)
      .def_property_readonly("path", &Material::path)
      .def_property_readonly("info_json", &Material::infoJson)
      .def("sizes", &Material::sizes)
      .def_property_readonly("width", [](const Material& s) { return s.decoder()->width(); })
      .def_property_readonly("height", [](const Material& s) { return s.decoder()->height(); })
      .def_property_readonly("alpha", [](const Material& s) { return s.decoder()->alpha(); })
      .def_property_readonly("lights", [](const Material& s) { return directionsArray(s.decoder()->lights()); })
      .def_property_readonly("views", [](const Material& s) { return directionsArray(s.decoder()->views()); })
      .def_property_readonly("isa", [](const Material& s) { return decoderIsaName(s.decoder()->isa()); })
      .def("query_angles", &Material::queryAngles, py::arg("texel"), py::arg("uv"), py::arg("light"),
           py::arg("view"), py::arg("normalized"))
      .def("query_vectors", &Material::queryVectors, py::arg("texel"), py::arg("uv"), py::arg("light"),
           py::arg("view"), py::arg("normalized"))
      .def("decode_image", &Material::decodeImage, py::arg("light"), py::arg("view"), py::arg("width"),
           py::arg("height"), py::arg("normalized"));

  m.def("load_stack", &loadStack, py::arg("path"), py::arg("crop"), py::arg("layout"), py::arg("linear"),
        py::arg("memory_limit"), py::arg("progress"), py::arg("quiet"));
  m.def("read_exr", &readImageLinear, py::arg("path"));
  m.def("set_threads", [](int threads) { setThreadCount(threads); }, py::arg("threads"));
  m.def("threads", [] { return threadCount(); });
}
