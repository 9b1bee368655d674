#include <doctest/doctest.h>

#include <vector>

#include "core/y4m.h"

using namespace st;

TEST_CASE("y4m: header format/parse round trip, 4:2:0 and mono") {
  for (Chroma c : {Chroma::k420, Chroma::kMono}) {
    const std::string h = format_y4m_header(641, 479, 30000, 1001, c);
    auto r = parse_y4m_header(h + "FRAME\n");
    REQUIRE(r.ok());
    CHECK(r->width == 641);
    CHECK(r->height == 479);
    CHECK(r->fps_num == 30000);
    CHECK(r->fps_den == 1001);
    CHECK(r->chroma == c);
    CHECK(r->header_bytes == h.size());
    CHECK(r->frame_bytes() == (c == Chroma::kMono ? 641u * 479u : 641u * 479u + 2u * 321u * 240u));
  }
}

TEST_CASE("y4m: frame writer packs planes and rejects wrong sizes") {
  const Y4mHeader h = parse_y4m_header(format_y4m_header(5, 3, 25, 1)).value();
  std::vector<std::uint8_t> y(5 * 3), u(3 * 2), v(3 * 2);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] = static_cast<std::uint8_t>(i);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = static_cast<std::uint8_t>(100 + i), v[i] = static_cast<std::uint8_t>(200 + i);
  std::string out;
  REQUIRE(append_y4m_frame(h, {y.data(), 5, 3}, {u.data(), 3, 2}, {v.data(), 3, 2}, &out).ok());
  CHECK(out.size() == 6 + h.frame_bytes());
  CHECK(parse_y4m_frame_line(out).value() == 6);
  CHECK(static_cast<std::uint8_t>(out[6 + 14]) == 14);
  CHECK(static_cast<std::uint8_t>(out[6 + 15]) == 100);
  CHECK(static_cast<std::uint8_t>(out[6 + 21]) == 200);
  std::string bad;
  CHECK_FALSE(append_y4m_frame(h, {y.data(), 4, 3}, {u.data(), 3, 2}, {v.data(), 3, 2}, &bad).ok());
  CHECK_FALSE(append_y4m_frame(h, {y.data(), 5, 3}, {u.data(), 2, 2}, {v.data(), 3, 2}, &bad).ok());
  CHECK(bad.empty());
}
