// Fuzzes scopetrack-register's pairs parser; accepted pairs must be finite,
// and a small accepted set goes on to the registration itself (P3P over
// every triple, LM), which must return a finite pose or an error.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "registration.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto pairs = st::parse_registration_pairs(std::string_view(reinterpret_cast<const char*>(data), size));
  if (!pairs) return 0;
  for (const st::RegistrationPair& p : pairs.value())
    if (!p.px.allFinite() || !p.p_model.allFinite()) __builtin_trap();
  if (pairs->size() > 12) return 0;  // C(12, 3) = 220 triples: keeps an input fast
  const st::CameraModel camera(st::Pinhole{900.0, 900.0, 639.5, 359.5, 1280, 720}, st::Distortion{});
  const auto result = st::register_first_frame(pairs.value(), camera);
  if (result && (!result->T_camera_model.all_finite() || !(result->rms_px >= 0.0))) __builtin_trap();
  return 0;
}
