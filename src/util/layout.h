// How a BTF stack is laid out and sampled: the facts a .nbtf file records about its source
// (the decoder writes the same layout back) and the stack loaders share.
#pragma once
#include <string>

namespace nbtf {

enum class SampleType { Srgb8, Half };
std::string sampleTypeName(SampleType t);

enum class Layout { Ubo2003, Utia, Unknown, Ubo2014 };  // Ubo2014: a Bonn .btf file (io/ubo2014_btf.h)
std::string layoutName(Layout l);
Layout parseLayout(const std::string& text);  // "ubo2003" | "utia" | "ubo2014"; throws otherwise

// A rectangle of texels (x, y, width, height) in the source images; empty = whole image.
struct Crop {
  int x = 0, y = 0, width = 0, height = 0;
  bool empty() const { return width == 0 && height == 0; }
  bool operator==(const Crop& o) const { return x == o.x && y == o.y && width == o.width && height == o.height; }
};
Crop parseCrop(const std::string& text);  // "X,Y,W,H"; throws on bad text or non-positive size

}  // namespace nbtf
