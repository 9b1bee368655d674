// The test binary links core, hal and platform but not the firmware_app
// sources; the BA tests need the real mapping thread, so its one source is
// compiled into the test binary here. (Lead: adding
// firmware_app/mapping_worker.cpp to the scopetrack-tests target in
// tests/CMakeLists.txt makes this file unnecessary.)
#include "firmware_app/mapping_worker.cpp"  // NOLINT(bugprone-suspicious-include)
