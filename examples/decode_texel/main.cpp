// decode_texel: what a renderer does with a .nbtf file, through the installed nbtf::decode
// library alone (no torch, no OpenCV, no OpenEXR).
//
//   decode_texel FILE.nbtf X Y THETA_L PHI_L THETA_V PHI_V [IMAGE.pfm]
//
// prints the linear RGB of texel (X, Y) lit from (THETA_L, PHI_L) and seen from
// (THETA_V, PHI_V) (degrees), as `nbtf query` does, and with IMAGE.pfm also writes the whole
// material at those angles as a portable float map (linear RGB, bottom row first).
#include <codec/decoder.h>
#include <util/error.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

void writePfm(const std::string& path, int width, int height, const std::vector<float>& rgb) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw nbtf::Error("cannot write '" + path + "'");
  std::fprintf(f, "PF\n%d %d\n-1.0\n", width, height);  // -1: little-endian floats
  for (int y = height - 1; y >= 0; --y)                  // PFM stores the bottom row first
    std::fwrite(rgb.data() + static_cast<std::size_t>(y) * width * 3, sizeof(float), static_cast<std::size_t>(width) * 3, f);
  if (std::fclose(f) != 0) throw nbtf::Error("cannot write '" + path + "'");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 8 && argc != 9) {
    std::fprintf(stderr, "usage: %s FILE.nbtf X Y THETA_L PHI_L THETA_V PHI_V [IMAGE.pfm]\n", argv[0]);
    return 2;
  }
  try {
    nbtf::NbtfDecoder decoder = nbtf::NbtfDecoder::open(argv[1]);
    const int x = std::atoi(argv[2]), y = std::atoi(argv[3]);
    const nbtf::Direction light{std::atof(argv[4]), std::atof(argv[5])};
    const nbtf::Direction view{std::atof(argv[6]), std::atof(argv[7])};
    nbtf::Rgb c = decoder.evaluate(x, y, light, view);
    std::printf("%.9g %.9g %.9g\n", c.r, c.g, c.b);
    if (argc == 9) {
      std::vector<float> image(3 * static_cast<std::size_t>(decoder.numTexels()));
      decoder.decodeImage(light, view, image.data());
      writePfm(argv[8], decoder.width(), decoder.height(), image);
    }
  } catch (const nbtf::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
