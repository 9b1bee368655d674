#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>

#include "hal/storage/file_io.h"
#include "hal/capture/y4m_reader.h"
#include "hal/storage/y4m_writer.h"
#include "support/alloc_guard.h"
#include "support/support.h"

using namespace st;

namespace {

// A deterministic 4:2:0 test video written by our writer.
void write_test_video(const std::filesystem::path& p, int w, int h, int frames, Chroma c) {
  Y4mWriter writer;
  Y4mHeader hdr;
  hdr.width = w;
  hdr.height = h;
  hdr.chroma = c;
  REQUIRE(writer.open(p, hdr).ok());
  Image<std::uint8_t> Y(w, h), U((w + 1) / 2, (h + 1) / 2), V((w + 1) / 2, (h + 1) / 2);
  for (int f = 0; f < frames; ++f) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) Y(x, y) = static_cast<std::uint8_t>(x + 3 * y + 7 * f);
    U.fill(static_cast<std::uint8_t>(f));
    V.fill(static_cast<std::uint8_t>(255 - f));
    REQUIRE(writer.write(Y.cview(), U.cview(), V.cview()).ok());
  }
  REQUIRE(writer.close().ok());
}

}  // namespace

TEST_CASE("y4m_reader: the real ffmpeg frame reads as one 1920x1080 4:2:0 frame") {
  Y4mReader r;
  REQUIRE(r.open(test::shared_data("real/laparoscopy_liver_1080p.y4m")).ok());
  CHECK(r.header().width == 1920);
  CHECK(r.header().height == 1080);
  CHECK(r.header().chroma == Chroma::k420);
  CHECK(r.header().fps_num == 25);
  FrameRef f;
  REQUIRE(r.read_frame(&f) == ReadResult::kFrame);
  CHECK(f.index == 0);
  CHECK(f.y.width == 1920);
  CHECK(f.u.width == 960);
  CHECK(f.v.height == 540);
  CHECK(f.y(0, 0) == 0x13);  // the black field-stop border, limited range
  CHECK(r.read_frame(&f) == ReadResult::kEndOfStream);
}

TEST_CASE("y4m_reader: writer/reader round trip, ring slots, zero allocations per frame") {
  const auto dir = test::scratch_dir("y4m_ring");
  write_test_video(dir / "v.y4m", 33, 17, 10, Chroma::k420);
  Y4mReader r;
  REQUIRE(r.open(dir / "v.y4m", 3).ok());
  FrameRef frames[10];
  REQUIRE(r.read_frame(&frames[0]) == ReadResult::kFrame);  // warm-up
  test::AllocationCounter allocs;
  for (int i = 1; i < 10; ++i) REQUIRE(r.read_frame(&frames[i]) == ReadResult::kFrame);
  CHECK(r.read_frame(&frames[0]) == ReadResult::kEndOfStream);
  CHECK(allocs.count() == 0);
  // The last 3 frames are still intact in the ring.
  for (int i = 7; i < 10; ++i) {
    CHECK(frames[i].index == i);
    CHECK(frames[i].y(5, 2) == static_cast<std::uint8_t>(5 + 6 + 7 * i));
    CHECK(frames[i].u(16, 8) == i);
    CHECK(frames[i].v(0, 0) == 255 - i);
  }
}

TEST_CASE("y4m_reader: truncated frame says which frame and how many bytes are missing") {
  const auto dir = test::scratch_dir("y4m_trunc");
  write_test_video(dir / "v.y4m", 16, 8, 3, Chroma::k420);
  std::string bytes = read_file(dir / "v.y4m", 1 << 20).value();
  bytes.resize(bytes.size() - 50);
  REQUIRE(write_file(dir / "t.y4m", bytes).ok());
  Y4mReader r;
  REQUIRE(r.open(dir / "t.y4m").ok());
  FrameRef f;
  CHECK(r.read_frame(&f) == ReadResult::kFrame);
  CHECK(r.read_frame(&f) == ReadResult::kFrame);
  test::AllocationCounter allocs;
  CHECK(r.read_frame(&f) == ReadResult::kError);
  CHECK(allocs.count() == 0);
  INFO(r.error());
  CHECK(r.error().find("frame 2 is truncated") != std::string::npos);
  CHECK(r.error().find("50 missing") != std::string::npos);
  CHECK(r.read_frame(&f) == ReadResult::kError);  // stays failed
  // A FRAME line cut in the middle and a corrupt record.
  REQUIRE(write_file(dir / "c.y4m", format_y4m_header(4, 2, 25, 1) + "FRA").ok());
  REQUIRE(r.open(dir / "c.y4m").ok());
  CHECK(r.read_frame(&f) == ReadResult::kError);
  CHECK(r.error().find("frame 0") != std::string::npos);
  REQUIRE(write_file(dir / "g.y4m", format_y4m_header(4, 2, 25, 1) + "GARBAGE\n" + std::string(12, 'x')).ok());
  REQUIRE(r.open(dir / "g.y4m").ok());
  CHECK(r.read_frame(&f) == ReadResult::kError);
}

TEST_CASE("y4m_reader: frames in pieces, with no slot: the same bytes, truncation counted, misuse refused") {
  const auto dir = test::scratch_dir("y4m_pieces");
  write_test_video(dir / "v.y4m", 33, 17, 3, Chroma::k420);
  Y4mReader whole, pieces;
  REQUIRE(whole.open(dir / "v.y4m", 1).ok());
  REQUIRE(pieces.open(dir / "v.y4m", 0).ok());
  CHECK(pieces.ring_slots() == 0);
  const std::size_t frame_bytes = pieces.header().frame_bytes();
  std::vector<std::uint8_t> buf(frame_bytes);
  test::AllocationCounter allocs;
  for (int i = 0; i < 3; ++i) {
    FrameRef f;
    REQUIRE(whole.read_frame(&f) == ReadResult::kFrame);
    int index = -1;
    REQUIRE(pieces.begin_frame(&index) == ReadResult::kFrame);
    CHECK(index == i);
    // Pieces of 1, 100 and the rest: the frame's bytes as read whole.
    REQUIRE(pieces.read_frame_data(buf.data(), 1) == ReadResult::kFrame);
    REQUIRE(pieces.read_frame_data(buf.data() + 1, 100) == ReadResult::kFrame);
    CHECK(pieces.frames_read() == i);  // not read until its last byte
    REQUIRE(pieces.read_frame_data(buf.data() + 101, frame_bytes - 101) == ReadResult::kFrame);
    CHECK(pieces.frames_read() == i + 1);
    CHECK(std::equal(buf.begin(), buf.end(), f.y.data));  // the slot holds Y, U and V in a row
  }
  int index = -1;
  CHECK(pieces.begin_frame(&index) == ReadResult::kEndOfStream);
  CHECK(allocs.count() == 0);

  // A frame that ends early: which frame, how many of its bytes were there.
  std::string bytes = read_file(dir / "v.y4m", 1 << 20).value();
  bytes.resize(bytes.size() - 300);
  REQUIRE(write_file(dir / "t.y4m", bytes).ok());
  REQUIRE(pieces.open(dir / "t.y4m", 0).ok());
  for (int i = 0; i < 2; ++i) {
    REQUIRE(pieces.begin_frame(&index) == ReadResult::kFrame);
    REQUIRE(pieces.read_frame_data(buf.data(), frame_bytes) == ReadResult::kFrame);
  }
  REQUIRE(pieces.begin_frame(&index) == ReadResult::kFrame);
  REQUIRE(pieces.read_frame_data(buf.data(), 200) == ReadResult::kFrame);
  CHECK(pieces.read_frame_data(buf.data(), frame_bytes - 200) == ReadResult::kError);
  INFO(pieces.error());
  CHECK(pieces.error().find("frame 2 is truncated: " + std::to_string(frame_bytes - 300) + " of " +
                            std::to_string(frame_bytes) + " bytes present, 300 missing") != std::string::npos);
  CHECK(pieces.begin_frame(&index) == ReadResult::kError);  // stays failed

  // Misuse: more bytes than the frame has, a new frame before the last
  // one's end, read_frame() without slots.
  REQUIRE(pieces.open(dir / "v.y4m", 0).ok());
  FrameRef f;
  CHECK(pieces.read_frame(&f) == ReadResult::kError);
  CHECK(pieces.error().find("without slots") != std::string::npos);
  REQUIRE(pieces.open(dir / "v.y4m", 0).ok());
  REQUIRE(pieces.begin_frame(&index) == ReadResult::kFrame);
  CHECK(pieces.read_frame_data(buf.data(), frame_bytes + 1) == ReadResult::kError);
  CHECK(pieces.error().find("past the end of frame 0") != std::string::npos);
  REQUIRE(pieces.open(dir / "v.y4m", 0).ok());
  REQUIRE(pieces.begin_frame(&index) == ReadResult::kFrame);
  REQUIRE(pieces.read_frame_data(buf.data(), 10) == ReadResult::kFrame);
  CHECK(pieces.begin_frame(&index) == ReadResult::kError);
  CHECK(pieces.error().find("still unread") != std::string::npos);
}

TEST_CASE("y4m_reader: bad streams fail at open with clear errors") {
  const auto dir = test::scratch_dir("y4m_bad");
  Y4mReader r;
  REQUIRE(write_file(dir / "empty.y4m", "").ok());
  Status s = r.open(dir / "empty.y4m");
  CHECK(s.message().find("empty stream") != std::string::npos);
  REQUIRE(write_file(dir / "magic.y4m", "GIF89a........\n").ok());
  s = r.open(dir / "magic.y4m");
  CHECK(s.message().find("YUV4MPEG2") != std::string::npos);
  REQUIRE(write_file(dir / "huge.y4m", "YUV4MPEG2 W65536 H65536 F25:1\nFRAME\n").ok());
  s = r.open(dir / "huge.y4m");
  CHECK(s.message().find("width") != std::string::npos);
  REQUIRE(write_file(dir / "zero.y4m", "YUV4MPEG2 W0 H0\n").ok());
  CHECK_FALSE(r.open(dir / "zero.y4m").ok());
  CHECK_FALSE(r.open(dir / "missing.y4m").ok());
  REQUIRE(write_file(dir / "ok.y4m", format_y4m_header(4, 2, 25, 1)).ok());
  CHECK_FALSE(r.open(dir / "ok.y4m", -1).ok());
  CHECK_FALSE(r.open(dir / "ok.y4m", kMaxRingSlots + 1).ok());
  REQUIRE(r.open(dir / "ok.y4m", 2).ok());
  FrameRef f;
  CHECK(r.read_frame(&f) == ReadResult::kEndOfStream);  // a header alone is an empty video
}

TEST_CASE("y4m_reader: Cmono written by ffmpeg reads back pixel-exact") {
  const auto dir = test::scratch_dir("y4m_mono");
  const int w = 97, h = 61;
  std::string pattern(static_cast<std::size_t>(w * h), '\0');
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      pattern[static_cast<std::size_t>(y * w + x)] = static_cast<char>((x * 7) ^ (y * 13));
  REQUIRE(write_file(dir / "pattern.raw", pattern).ok());
  const std::string cmd = std::string(SCOPETRACK_FFMPEG) +
                          " -hide_banner -loglevel error -y -f rawvideo -pix_fmt gray -s " +
                          std::to_string(w) + "x" + std::to_string(h) + " -i " +
                          (dir / "pattern.raw").string() + " -f yuv4mpegpipe -pix_fmt gray " +
                          (dir / "out.y4m").string();
  REQUIRE(std::system(cmd.c_str()) == 0);
  Y4mReader r;
  REQUIRE(r.open(dir / "out.y4m").ok());
  CHECK(r.header().chroma == Chroma::kMono);
  CHECK(r.header().chroma_tag == "mono");
  FrameRef f;
  REQUIRE(r.read_frame(&f) == ReadResult::kFrame);
  CHECK(f.u.empty());
  int mismatches = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      mismatches += f.y(x, y) != static_cast<std::uint8_t>(pattern[static_cast<std::size_t>(y * w + x)]);
  CHECK(mismatches == 0);
  CHECK(r.read_frame(&f) == ReadResult::kEndOfStream);
}

TEST_CASE("y4m_reader: reads ffmpeg writing into a FIFO") {
  const auto dir = test::scratch_dir("y4m_fifo");
  const auto fifo = dir / "pipe.y4m";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  // ffmpeg generates 12 frames of a test pattern and writes them into the FIFO.
  const std::string cmd = std::string(SCOPETRACK_FFMPEG) +
                          " -hide_banner -loglevel error -y -f lavfi -i testsrc=size=64x48:rate=25 "
                          "-frames:v 12 -pix_fmt yuv420p -f yuv4mpegpipe " + fifo.string() + " &";
  REQUIRE(std::system(cmd.c_str()) == 0);
  Y4mReader r;
  REQUIRE(r.open(fifo, 4).ok());  // blocks until ffmpeg opens the FIFO
  CHECK(r.header().width == 64);
  FrameRef f;
  int frames = 0;
  ReadResult res;
  while ((res = r.read_frame(&f)) == ReadResult::kFrame) ++frames;
  CHECK(res == ReadResult::kEndOfStream);
  CHECK(frames == 12);
}

TEST_CASE("y4m_reader: reads a pipe given as a descriptor") {
  const auto dir = test::scratch_dir("y4m_pipe");
  write_test_video(dir / "v.y4m", 20, 10, 5, Chroma::kMono);
  const std::string bytes = read_file(dir / "v.y4m", 1 << 20).value();
  int fds[2];
  REQUIRE(::pipe(fds) == 0);
  std::thread writer([&] {
    std::size_t done = 0;
    while (done < bytes.size()) {  // small writes: the reader sees partial frames
      const ssize_t n = ::write(fds[1], bytes.data() + done, std::min<std::size_t>(37, bytes.size() - done));
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    ::close(fds[1]);
  });
  Y4mReader r;
  REQUIRE(r.open_fd(fds[0], true, 2, "pipe").ok());
  FrameRef f;
  int frames = 0;
  while (r.read_frame(&f) == ReadResult::kFrame) {
    CHECK(f.y(3, 2) == static_cast<std::uint8_t>(3 + 6 + 7 * frames));
    ++frames;
  }
  writer.join();
  CHECK(frames == 5);
  CHECK(r.error().empty());
}
