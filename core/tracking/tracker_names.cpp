// Names of the tracker's enums (core/tracking/tracker.h), apart from the tracker
// itself: host tools and fuzz targets that print a state link this alone.
#include "core/tracking/tracker.h"

namespace st {

const char* to_string(TrackState s) {
  switch (s) {
    case TrackState::kInitialised: return "initialised";
    case TrackState::kTracking: return "tracking";
    case TrackState::kRelocalised: return "relocalised";
    case TrackState::kLost: return "lost";
  }
  return "?";
}

const char* to_string(Stage s) {
  switch (s) {
    case Stage::kScale: return "scale";
    case Stage::kPyramid: return "pyramid";
    case Stage::kOccluder: return "occluder";
    case Stage::kRaster: return "raster";
    case Stage::kDetect: return "detect";
    case Stage::kDescribe: return "describe";
    case Stage::kMatch: return "match";
    case Stage::kPose: return "pose";
    case Stage::kMap: return "map";
    case Stage::kReloc: return "reloc";
    case Stage::kContour: return "contour";
    case Stage::kTotal: return "total";
    case Stage::kCount: break;
  }
  return "?";
}

}  // namespace st
