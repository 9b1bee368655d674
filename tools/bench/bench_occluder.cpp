// Stage "occluder": OccluderMaskBuilder::build (core/image/occluder_mask.h) at the
// tracker's 1280x720, on the middle 1280x720 of the real frame of
// shared/data (tissue, no instrument: the colour test alone, nothing to
// clean) and on the same crop with a grey, instrument-like band painted
// across it (~13 % of the frame: colour test, opening and margin).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include "bench.h"
#include "core/image/image.h"
#include "core/image/occluder_mask.h"
#include "hal/capture/y4m_reader.h"

namespace st::bench {
namespace {

constexpr int kWidth = 1280, kHeight = 720;

struct Planes {
  Image<std::uint8_t> y{kWidth, kHeight}, u{kWidth / 2, kHeight / 2}, v{kWidth / 2, kHeight / 2};
};

// The middle kWidth x kHeight of frame (even offsets keep the chroma sited).
void crop(const FrameRef& f, Planes* p) {
  const int x0 = ((f.y.width - kWidth) / 2) & ~1, y0 = ((f.y.height - kHeight) / 2) & ~1;
  for (int y = 0; y < kHeight; ++y)
    std::copy_n(f.y.row(y0 + y) + x0, kWidth, p->y.data() + static_cast<std::ptrdiff_t>(y) * kWidth);
  for (int y = 0; y < kHeight / 2; ++y) {
    std::copy_n(f.u.row(y0 / 2 + y) + x0 / 2, kWidth / 2, p->u.data() + static_cast<std::ptrdiff_t>(y) * (kWidth / 2));
    std::copy_n(f.v.row(y0 / 2 + y) + x0 / 2, kWidth / 2, p->v.data() + static_cast<std::ptrdiff_t>(y) * (kWidth / 2));
  }
}

// A grey shaft from the top-left corner towards the middle, 90 px wide,
// shaded across its width like a cylinder.
void paint_shaft(Planes* p) {
  const double dx = 0.8, dy = 0.6;  // unit direction
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) {
      const double along = x * dx + y * dy, across = -x * dy + y * dx;
      if (along > 900 || std::abs(across) > 45) continue;
      p->y(x, y) = static_cast<std::uint8_t>(60 + 100 * std::cos(across / 45 * 1.4));
      if ((x & 1) == 0 && (y & 1) == 0) {
        p->u(x / 2, y / 2) = 130;
        p->v(x / 2, y / 2) = 131;
      }
    }
}

Row time_build(const std::string& name, const Planes& p, int iterations) {
  OccluderMaskBuilder b;
  Row row{name, {}, "", {}, ""};
  if (!b.configure(OccluderMaskConfig{}, kWidth, kHeight).ok()) return row;
  for (int i = 0; i < iterations + 5; ++i) {
    const double t0 = now_ms();
    b.build(p.y.cview(), p.u.cview(), p.v.cview());
    if (i >= 5) row.samples_ms.push_back(now_ms() - t0);
  }
  const double n = static_cast<double>(b.mask_width()) * b.mask_height();
  row.note = std::to_string(b.candidate_pixels()) + " candidates, " +
             std::to_string(static_cast<int>(std::lround(100.0 * b.flagged_pixels() / n))) + " % flagged";
  return row;
}

int run_occluder(const Options& opt) {
  const int iterations = opt.iterations > 0 ? opt.iterations : 200;
  const auto path = std::filesystem::path(opt.shared_dir) / "data/real/laparoscopy_liver_1080p.y4m";
  Y4mReader reader;
  FrameRef f;
  if (!reader.open(path).ok() || reader.read_frame(&f) != ReadResult::kFrame || f.u.empty() ||
      f.y.width < kWidth || f.y.height < kHeight) {
    info(opt, "occluder: cannot read a 4:2:0 frame of at least 1280x720 from " + path.string());
    return 1;
  }
  Planes p;
  crop(f, &p);
  report(opt, time_build("occluder mask 1280x720, real tissue", p, iterations));
  paint_shaft(&p);
  report(opt, time_build("occluder mask 1280x720, + grey shaft", p, iterations));
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("occluder", "occluder mask from chroma (1280x720): tissue alone, and with a grey shaft",
                       run_occluder);

}  // namespace st::bench
