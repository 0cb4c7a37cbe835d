// Light and view directions on the upper hemisphere, the 81-direction UBO2003/UTIA
// sampling, and the stereographic projection the decoder takes as input.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace nbtf {

// A direction on the upper hemisphere: theta is the polar angle from the surface
// normal, phi the azimuth, both in degrees (the units the data sets' file names use).
struct Direction {
  double thetaDeg = 0;
  double phiDeg = 0;

  std::array<double, 3> unitVector() const;
  static Direction fromUnitVector(double x, double y, double z);
  bool operator==(const Direction& o) const { return thetaDeg == o.thetaDeg && phiDeg == o.phiDeg; }
};

// Throws nbtf::Error if the direction is below the horizon (theta > 90) or not finite.
// `what` names the direction in the message (e.g. "light").
void checkHemisphere(const Direction& d, const std::string& what);

// The 81 directions of UBO2003/UTIA: rings theta = 0..75 step 15 with 1, 6, 12, 18, 20, 24
// directions, phi evenly spaced from 0; ring ascending, then phi ascending.
const std::vector<Direction>& hemisphere81();

// Stereographic projection of eq. (7)-(9) of the clustered neural BTF paper:
// R = sin(pi - theta) / (1 - cos(pi - theta)), x = R cos(phi), y = R sin(phi).
// Maps the hemisphere into the unit disk (theta = 90 -> R = 1, theta = 0 -> R = 0).
std::array<float, 2> stereographic(const Direction& d);

// How a (light, view) pair is fed to the decoder, after the latent (the "model.direction_inputs"
// key of a config; stored in the .nbtf, so values are never renumbered). Stereographic is the
// paper's eq. (7)-(9): (x, y) of the light, then of the view (4 inputs). StereographicHalf
// (format 1.3) adds the unit half vector h = (l + v) / |l + v| and cos(theta_d) = l . h
// (8 inputs): highlights and Fresnel-like effects are simple functions of them (Rusinkiewicz's
// parameterization), which the decoder would otherwise build from the stereographic
// coordinates with its own layers. StereographicFourier (format 1.6) adds, for each of the 4
// stereographic coordinates c, sin(2^o pi c) and cos(2^o pi c) for octaves o = 0..2 (4 + 24
// inputs): a ReLU network fits sharp angular features from them in far fewer steps than from
// the coordinates alone (the spectral bias of MLPs; Tancik et al. 2020, Fourier features).
// StereographicFourier2 (format 1.7, the default) stops at octave 1 (4 + 16 inputs): octave 2
// fits the measured images a little better but interpolates specular peaks between them worse.
enum class DirectionEncoding : std::uint8_t {
  Stereographic = 1,
  StereographicHalf = 2,
  StereographicFourier = 3,
  StereographicFourier2 = 4
};
constexpr int kMaxFourierOctaves = 3;
constexpr int kMaxDirectionInputs = 4 + 4 * 2 * kMaxFourierOctaves;
bool isDirectionEncoding(int code);                              // a value this build knows
std::vector<DirectionEncoding> directionEncodings();            // every encoding this build knows, by code
int fourierOctaves(DirectionEncoding encoding);                  // 3, 2, or 0 for the encodings without them
int directionInputCount(DirectionEncoding encoding);             // 4, 8, 28 or 20
// "stereographic" | "stereographic+half" | "stereographic+fourier" | "stereographic+fourier2"
std::string directionEncodingName(DirectionEncoding encoding);
// What the inputs are, for info and reports ("stereographic projection (eq. 7-9), ... (N inputs)").
std::string directionEncodingDescription(DirectionEncoding encoding);
// Throws nbtf::Error naming the accepted names.
DirectionEncoding parseDirectionEncoding(const std::string& name);
// Writes directionInputCount(encoding) floats. Light and view are unit vectors (z = the normal).
void encodeDirections(DirectionEncoding encoding, const std::array<double, 3>& light, const std::array<double, 3>& view,
                      float* out);
void encodeDirections(DirectionEncoding encoding, const Direction& light, const Direction& view, float* out);

// "THETA,PHI" in degrees -> Direction; throws nbtf::Error naming `what` on bad text.
Direction parseDirection(const std::string& text, const std::string& what);

// "(15°, 60°)": a direction in messages and reports (degrees to 0.001).
std::string formatDirection(const Direction& d);
// The same direction to within 0.001 degrees (the angle between the unit vectors).
bool sameDirection(const Direction& a, const Direction& b);
// A stack compared with (or rendered beside) a material must have been measured at the same
// directions: throws nbtf::Error, `prefix` + "the reference has N light directions, the file M"
// or the first direction that differs (`what`: "light" or "view").
void checkSameDirections(const std::vector<Direction>& reference, const std::vector<Direction>& file,
                         const char* what, const std::string& prefix);

// Index of the nearest direction in `set` by angle between unit vectors.
int nearestDirection(const std::vector<Direction>& set, const Direction& d);

}  // namespace nbtf
