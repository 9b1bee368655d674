// A fixture for the layer rule's test (tests/CMakeLists.txt): a header that
// includes only the stages it may use. Never compiled.
#pragma once
#include <cstdint>

#include "core/base/result.h"
#include "core/geometry/se3.h"
