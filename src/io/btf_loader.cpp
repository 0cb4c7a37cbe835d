#include "io/btf_loader.h"

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "io/btf_names.h"
#include "io/image_io.h"
#include "io/ubo2014_btf.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/scratch_mapping.h"

namespace nbtf {
namespace fs = std::filesystem;

namespace {

// Directions compare by angle; sort ring ascending, then phi ascending.
struct DirLess {
  bool operator()(const Direction& a, const Direction& b) const {
    return a.thetaDeg != b.thetaDeg ? a.thetaDeg < b.thetaDeg : a.phiDeg < b.phiDeg;
  }
};

// An nbtf decode or nbtf-synth run writes its description ("complete": false) before its first
// image and marks it complete after the last: a folder whose description says otherwise was
// interrupted, and its images are a part of the material, or two materials mixed.
void refuseInterruptedOutput(const fs::path& folder) {
  // A decode's staging folder, even one killed before its description was written.
  const fs::path named = folder.filename().empty() ? folder.parent_path() : folder;  // "dir/" -> "dir"
  const std::string base = named.filename().string(), suffix = kDecodeStagingSuffix;
  if (base.size() > suffix.size() + 1 && base[0] == '.' && base.compare(base.size() - suffix.size(), suffix.size(), suffix) == 0)
    throw fileError(folder.string(), "is the staging folder of an interrupted nbtf decode: run the decode again");
  for (const char* name : {kDecodeDescriptionName, "synth.json"}) {
    const fs::path description = folder / name;
    std::error_code ec;
    if (!fs::is_regular_file(description, ec)) continue;
    std::ifstream in(description);
    const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (j.is_object() && j.contains("complete") && j["complete"] == false)
      throw fileError(folder.string(), std::string("is the output of an interrupted ") +
                                           (name == std::string("synth.json") ? "nbtf-synth run" : "nbtf decode") +
                                           " (" + name + " says \"complete\": false): run it again");
  }
}

std::string describe(const Direction& d) {
  std::ostringstream s;
  s << "(theta " << d.thetaDeg << ", phi " << d.phiDeg << ")";
  return s.str();
}

// A UBO2014 file's listing: its own directions (reading the factors is the check that they
// fit); --layout may only confirm it.
StackListing ubo2014Listing(const std::string& path, Layout forced, const Ubo2014Btf& btf) {
  if (forced != Layout::Unknown && forced != Layout::Ubo2014)
    throw fileError(path, "is a UBO2014 .btf file: --layout " + layoutName(forced) +
                              " applies to folders of images only (leave it out, or give --layout ubo2014)");
  StackListing listing;
  listing.layout = Layout::Ubo2014;
  listing.lights = btf.meta().lights;
  listing.views = btf.meta().views;
  return listing;
}

// Candidate image files: the folder's own and its view folders', each in name order.
std::vector<fs::path> candidateImages(const std::string& path) {
  std::error_code ec;
  std::vector<fs::path> candidates;
  std::size_t otherFiles = 0;
  std::vector<fs::path> entries;
  for (const auto& e : fs::directory_iterator(path, ec)) entries.push_back(e.path());
  if (ec) throw fileAccessError(path, "cannot list folder: " + ec.message(), ec.value());
  std::sort(entries.begin(), entries.end());
  for (const auto& p : entries) {
    if (fs::is_directory(p, ec)) {
      if (!isViewFolderName(p.filename().string())) continue;
      std::vector<fs::path> inner;
      for (const auto& e : fs::directory_iterator(p, ec)) inner.push_back(e.path());
      std::sort(inner.begin(), inner.end());
      for (const auto& q : inner) {
        if (fs::is_regular_file(q, ec) && isImageFileName(q.filename().string())) candidates.push_back(q);
        else if (fs::is_regular_file(q, ec)) ++otherFiles;
      }
    } else if (fs::is_regular_file(p, ec)) {
      if (isImageFileName(p.filename().string())) candidates.push_back(p);
      else ++otherFiles;
    }
  }
  if (candidates.empty()) {
    if (entries.empty()) throw fileError(path, "folder is empty: no BTF images found");
    std::ostringstream s;
    s << "no BTF images found (" << entries.size() << " entries, " << otherFiles
      << " non-image files; expected view folders like 'tv030_pv030/' or images named like "
         "'tl000_pl000_tv000_pv000.png' / '00008 tl000 pl000 tv030 pv030.jpg')";
    throw fileError(path, s.str());
  }
  return candidates;
}

// Every candidate's directions from its name (an image in a view folder or among other BTF
// images must have them), and per layout the names that are in it.
std::vector<StackFile> parseStackNames(const std::vector<fs::path>& candidates, std::map<int, int>& layoutVotes) {
  std::vector<StackFile> files;
  for (const auto& p : candidates) {
    std::optional<ParsedBtfName> parsed;
    try {
      parsed = parseBtfFileName(p.filename().string());
    } catch (const Error& e) {
      throw fileError(p.string(), std::string(e.what()).substr(p.filename().string().size() + 2));
    }
    if (!parsed) throw fileError(p.string(), "image name does not parse (no tl/pl/tv/pv angle tokens)");
    files.push_back({p.string(), parsed->light, parsed->view, parsed->index});
    layoutVotes[static_cast<int>(parsed->layout)]++;
  }
  return files;
}

// --layout where given, else the layout most names are in (ubo2003 on a tie).
Layout stackLayout(const std::string& path, Layout forced, const std::vector<StackFile>& files,
                   std::map<int, int>& layoutVotes) {
  if (forced == Layout::Utia && layoutVotes[static_cast<int>(Layout::Utia)] == 0) {
    // Every name carries UBO2003's running index: forcing UTIA would change nothing but the
    // colour space of EXR images, silently. (Names without an index may be either layout, so
    // --layout ubo2003 over them is honoured.)
    throw fileError(path, "--layout utia: the images are named in the ubo2003 layout, with a running index (e.g. '" +
                              fs::path(files.front().path).filename().string() +
                              "'); leave --layout out or give --layout ubo2003");
  }
  if (forced != Layout::Unknown) return forced;
  return layoutVotes[static_cast<int>(Layout::Ubo2003)] >= layoutVotes[static_cast<int>(Layout::Utia)]
             ? Layout::Ubo2003
             : Layout::Utia;
}

// The sorted light and view directions of `files`, and each file in its slot; every slot
// filled exactly once.
void placeStackFiles(const std::string& path, const std::vector<StackFile>& files, StackListing& listing) {
  std::set<Direction, DirLess> lightSet, viewSet;
  for (const auto& f : files) lightSet.insert(f.light), viewSet.insert(f.view);
  listing.lights.assign(lightSet.begin(), lightSet.end());
  listing.views.assign(viewSet.begin(), viewSet.end());
  std::map<Direction, int, DirLess> lightIndex, viewIndex;
  for (std::size_t i = 0; i < listing.lights.size(); ++i) lightIndex[listing.lights[i]] = static_cast<int>(i);
  for (std::size_t i = 0; i < listing.views.size(); ++i) viewIndex[listing.views[i]] = static_cast<int>(i);

  std::size_t nl = listing.lights.size(), nv = listing.views.size();
  listing.files.assign(nl * nv, std::string());
  for (const auto& f : files) {
    std::size_t slot = lightIndex[f.light] * nv + viewIndex[f.view];
    if (!listing.files[slot].empty())
      throw fileError(f.path, "duplicate image: light " + describe(f.light) + " x view " + describe(f.view) +
                                  " is also in '" + listing.files[slot] + "'");
    listing.files[slot] = f.path;
  }
  std::size_t missing = std::count(listing.files.begin(), listing.files.end(), std::string());
  if (missing > 0) {
    for (std::size_t slot = 0; slot < listing.files.size(); ++slot) {
      if (!listing.files[slot].empty()) continue;
      const Direction& l = listing.lights[slot / nv];
      const Direction& v = listing.views[slot % nv];
      std::string folder = (fs::path(path) / viewFolderName(v)).string();
      std::ostringstream s;
      s << "incomplete stack: " << missing << " of " << nl * nv << " images missing (" << nl << " lights x " << nv
        << " views on disk); first missing: light " << describe(l) << " x view " << describe(v) << " (expected in '"
        << folder << "' or '" << path << "')";
      throw fileError(path, s.str());
    }
  }
}

}  // namespace

StackListing listBtfStack(const std::string& path, Layout forced) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw fileAccessError(path, "no such file or folder", ENOENT);
  if (looksLikeUbo2014(path)) return ubo2014Listing(path, forced, Ubo2014Btf::read(path));
  if (!fs::is_directory(path, ec))
    throw fileAccessError(path, "not a folder (expected a folder of BTF images or a UBO2014 .btf file)", ENOTDIR);
  if (forced == Layout::Ubo2014)
    throw fileError(path, "is a folder of images: --layout ubo2014 applies to UBO2014 .btf files only (leave it "
                          "out, or give ubo2003 or utia)");
  refuseInterruptedOutput(path);

  std::map<int, int> layoutVotes;
  const std::vector<StackFile> files = parseStackNames(candidateImages(path), layoutVotes);
  StackListing listing;
  listing.layout = stackLayout(path, forced, files, layoutVotes);
  placeStackFiles(path, files, listing);
  return listing;
}

namespace {
// The size of the stack's first image (every other image must have it), and the crop
// checked against it.
Crop cropFor(const std::string& path, const StackListing& listing, const LoadOptions& options, int& srcW, int& srcH) {
  const std::string& first = listing.files.front();
  if (imageFormatFromName(first) == ImageFormat::Exr) {
    ExrColorSpace exrSpace =
        (listing.layout == Layout::Utia && options.utiaExrIsXyz) ? ExrColorSpace::CieXyz : ExrColorSpace::LinearSrgb;
    ImageF img = readExr(first, exrSpace);
    srcW = img.width, srcH = img.height;
  } else {
    Image8 img = readImage8(first);
    srcW = img.width, srcH = img.height;
  }
  Crop crop = options.crop;
  if (crop.empty()) crop = {0, 0, srcW, srcH};
  if (crop.x + crop.width > srcW || crop.y + crop.height > srcH) {
    std::ostringstream s;
    s << "crop " << crop.x << "," << crop.y << "," << crop.width << "," << crop.height << " lies outside the "
      << srcW << " x " << srcH << " images";
    throw fileError(path, s.str());
  }
  return crop;
}
}  // namespace

namespace {
// Whether a UBO2014 file's crop stays factorized: its half-float expansion is over the limit.
bool keepFactorized(const Ubo2014Btf& btf, const LoadOptions& options) {
  const Crop& c = options.crop;
  const std::size_t texels = c.empty() ? static_cast<std::size_t>(btf.numTexels())
                                       : static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height);
  return texels * static_cast<std::size_t>(btf.numImages()) * 3 * 2 > options.expandUpTo;
}
}  // namespace

BtfInput resolveBtfInput(const std::string& path, const LoadOptions& options) {
  BtfInput in;
  in.path = path;
  in.cropped = !options.crop.empty();
  StackShape& shape = in.shape;
  if (looksLikeUbo2014(path)) {
    auto btf = std::make_shared<const Ubo2014Btf>(Ubo2014Btf::read(path));
    in.listing = ubo2014Listing(path, options.layout, *btf);
    shape.lights = btf->numLights(), shape.views = btf->numViews();
    in.sourceWidth = btf->width(), in.sourceHeight = btf->height();
    in.crop = btf->checkedCrop(options.crop);
    in.factorized = keepFactorized(*btf, options);
    shape.type = SampleType::Half;  // the crop's values as half floats, stored or computed
    shape.width = in.crop.width, shape.height = in.crop.height;
    if (in.factorized)
      shape.computedBytes = btf->factorBytes() + ubo2014ComputedBlockBytes(in.crop.width * in.crop.height, btf->numImages());
    in.ubo2014 = std::move(btf);
    return in;
  }
  in.listing = listBtfStack(path, options.layout);
  shape.lights = static_cast<int>(in.listing.lights.size()), shape.views = static_cast<int>(in.listing.views.size());
  in.crop = cropFor(path, in.listing, options, in.sourceWidth, in.sourceHeight);
  shape.width = in.crop.width, shape.height = in.crop.height;
  shape.type = imageFormatFromName(in.listing.files.front()) == ImageFormat::Exr ? SampleType::Half : SampleType::Srgb8;
  return in;
}

Crop checkCrop(const std::string& path, const LoadOptions& options) { return resolveBtfInput(path, options).crop; }

StackShape stackShape(const std::string& path, const LoadOptions& options) {
  return resolveBtfInput(path, options).shape;
}

BtfStack loadBtfStack(const std::string& path, const LoadOptions& options) {
  return loadBtfStack(resolveBtfInput(path, options), options);
}

BtfStack loadBtfStack(const BtfInput& in, const LoadOptions& options) {
  // A UBO2014 file: the crop's texels are expanded when that is small enough, else computed
  // from the factors when read (the same values either way).
  const Crop asked = in.cropped ? in.crop : Crop{};
  if (in.ubo2014) {
    if (in.factorized) return Ubo2014Btf::computedStack(in.ubo2014, asked);
    return in.ubo2014->toStack(asked, options.progress);
  }
  const StackListing& listing = in.listing;
  const std::string& first = listing.files.front();
  const bool exr = in.shape.type == SampleType::Half;
  const ExrColorSpace exrSpace =
      (listing.layout == Layout::Utia && options.utiaExrIsXyz) ? ExrColorSpace::CieXyz : ExrColorSpace::LinearSrgb;
  const int srcW = in.sourceWidth, srcH = in.sourceHeight;
  const Crop& crop = in.crop;

  BtfStack stack(listing.lights, listing.views, crop.width, crop.height, in.shape.type, options.scratchDir);
  stack.source = in.path;
  stack.layout = listing.layout;
  stack.sourceWidth = srcW;
  stack.sourceHeight = srcH;
  stack.crop = asked;

  Progress progress("load", listing.files.size(), options.progress);
  parallelForDynamic(listing.files.size(), [&](std::size_t i, int) {
    const std::string& file = listing.files[i];
    if ((imageFormatFromName(file) == ImageFormat::Exr) != exr)
      throw fileError(file, std::string("mixed formats: this stack's first image '") + first + "' is " +
                                (exr ? "EXR" : "8-bit") + ", this one is not");
    auto checkSize = [&](int w, int h) {
      if (w != srcW || h != srcH) {
        std::ostringstream s;
        s << "image is " << w << " x " << h << ", but the stack's first image '" << first << "' is " << srcW
          << " x " << srcH;
        throw fileError(file, s.str());
      }
    };
    if (exr) {
      ImageF img = readExr(file, exrSpace);
      checkSize(img.width, img.height);
      std::vector<float> rows(static_cast<std::size_t>(crop.width) * crop.height * 3);
      for (int y = 0; y < crop.height; ++y)
        std::copy_n(img.rgb.data() + (static_cast<std::size_t>(crop.y + y) * srcW + crop.x) * 3, crop.width * 3,
                    rows.data() + static_cast<std::size_t>(y) * crop.width * 3);
      stack.setImageLinear(static_cast<int>(i), rows.data());
    } else {
      Image8 img = readImage8(file);
      checkSize(img.width, img.height);
      if (crop.width == srcW && crop.height == srcH) {
        stack.writeImageBytes(static_cast<int>(i), img.rgb.data());
      } else {
        std::vector<std::uint8_t> rows(static_cast<std::size_t>(crop.width) * crop.height * 3);
        for (int y = 0; y < crop.height; ++y)
          std::copy_n(img.rgb.data() + (static_cast<std::size_t>(crop.y + y) * srcW + crop.x) * 3, crop.width * 3,
                      rows.data() + static_cast<std::size_t>(y) * crop.width * 3);
        stack.writeImageBytes(static_cast<int>(i), rows.data());
      }
    }
    // A stack in a scratch file relies on the file cache holding it: the images, read once,
    // must not take that room.
    if (stack.inScratchFile()) dropFromFileCache(file);
    progress.advance();
  });
  progress.finish();
  return stack;
}

}  // namespace nbtf
