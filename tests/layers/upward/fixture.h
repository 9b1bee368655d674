// A fixture for the layer rule's test (tests/CMakeLists.txt): a header of a
// low stage that includes the tracker, a stage above it. Never compiled.
#pragma once
#include <cstdint>

#include "core/geometry/se3.h"
#include "core/tracking/tracker.h"
