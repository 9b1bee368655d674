#include <doctest/doctest.h>

#include <vector>

#include "core/formats/y4m.h"

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

TEST_CASE("y4m: ffmpeg header with X-tags, C420 variants, no C tag") {
  auto r = parse_y4m_header(
      "YUV4MPEG2 W1920 H1080 F25:1 Ip A1:1 C420jpeg XYSCSS=420JPEG XCOLORRANGE=LIMITED\nFRAME\n");
  REQUIRE(r.ok());
  CHECK(r->width == 1920);
  CHECK(r->chroma_tag == "420jpeg");
  CHECK(r->header_bytes == 80);
  for (const char* tag : {" C420paldv", " C420mpeg2", " C420", ""}) {
    auto h = parse_y4m_header(std::string("YUV4MPEG2 W4 H2 F30:1") + tag + "\n");
    REQUIRE(h.ok());
    CHECK(h->chroma == Chroma::k420);
    CHECK(h->frame_bytes() == 8 + 2 * 2);
  }
  auto frame = parse_y4m_frame_line("FRAME Ixyz XFOO=1\n\x10\x10");
  REQUIRE(frame.ok());
  CHECK(frame.value() == 18);
}

TEST_CASE("y4m: bad headers and FRAME lines give clear errors") {
  struct Case { std::string bytes; const char* needle; };
  const Case cases[] = {
      {"", "must start with 'YUV4MPEG2'"},
      {"RIFF\x00\x01", "must start with 'YUV4MPEG2'"},
      {"YUV4MPEG2 W640 H480 F25:1 C420jpeg", "no end"},                  // truncated header
      {"YUV4MPEG2 W0 H480\n", "width"},
      {"YUV4MPEG2 W640 H0\n", "height"},
      {"YUV4MPEG2 W-5 H480\n", "width"},
      {"YUV4MPEG2 W100000 H480\n", "width"},                             // absurd, capped
      {"YUV4MPEG2 W99999999999999999999 H480\n", "width"},               // overflow
      {"YUV4MPEG2 W640 H480 C444\n", "not supported"},
      {"YUV4MPEG2 W640 H480 Cmono16\n", "not supported"},
      {"YUV4MPEG2 W640 H480 F25:0\n", "frame rate"},
      {"YUV4MPEG2 W640 F25:1\n", "frame size"},
      {"YUV4MPEG2W640 H480\n", "followed by a space"},
      {"YUV4MPEG2 W640 H480 " + std::string(5000, 'X') + "\n", "no end"},
  };
  for (const Case& c : cases) {
    auto r = parse_y4m_header(c.bytes);
    REQUIRE_FALSE(r.ok());
    INFO(r.message());
    CHECK(r.message().find(c.needle) != std::string::npos);
  }
  CHECK_FALSE(parse_y4m_frame_line("FRAMX\n").ok());
  CHECK_FALSE(parse_y4m_frame_line("FRAME").ok());
  CHECK_FALSE(parse_y4m_frame_line("FRAMEX\n").ok());
  CHECK_FALSE(parse_y4m_frame_line("").ok());
}
