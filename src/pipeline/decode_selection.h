// Which images a decode writes: the lights and views (--lights / --views lists, --light /
// --view directions, measured or not) and the output size (--size WxH).
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "util/directions.h"

namespace nbtf {

// A light or view to decode: a measured direction (index into the material's list) or
// any other direction on the hemisphere (index -1).
struct DirectionChoice {
  Direction direction;
  int index = -1;
  bool measured() const { return index >= 0; }
};

// Parses a --lights / --views LIST (`option` names it in errors):
//   all                 every measured direction (the default)
//   ITEM[,ITEM...]      items in the order given, duplicates removed
//   ITEM = N            measured direction number N (0-based, in the order the loader sorts
//                       them: theta ascending, then phi; 0..80 for the 81-direction sets)
//        | N-M          measured directions N to M inclusive
//        | tTHETApPHI   the direction (THETA, PHI) in degrees, e.g. t37.5p200; a measured
//                       direction when it is one (to 1e-6 degrees), else unmeasured
std::vector<DirectionChoice> parseDirectionList(const std::string& text, const std::vector<Direction>& measured,
                                                const std::string& option);
// One direction as THETA,PHI degrees (for --light / --view), matched to a measured one when equal.
DirectionChoice chooseDirection(const Direction& d, const std::vector<Direction>& measured);
std::vector<DirectionChoice> allDirections(const std::vector<Direction>& measured);

// "WxH" -> (width, height), both in 1..maxSide; throws naming `option`.
std::pair<int, int> parseImageSize(const std::string& text, const std::string& option, int maxSide = 1 << 16);

}  // namespace nbtf
