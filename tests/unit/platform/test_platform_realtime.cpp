// platform/realtime.h: the background workers' priority.
#include <doctest/doctest.h>

#include <algorithm>
#include <string>
#include <thread>

#include "platform/realtime.h"

using namespace st;

TEST_CASE("set_thread_nice lowers the calling thread only, values outside 0..19 are refused") {
  const int main_before = platform::thread_nice();
  // A process started under nice keeps its own (higher) value in the worker.
  const int expected = std::max(main_before, platform::kBackgroundWorkerNice);
  platform::RealtimeReport report;
  int worker_nice = -100;
  std::thread worker([&] {
    report = platform::set_thread_nice(platform::kBackgroundWorkerNice);
    worker_nice = platform::thread_nice();
  });
  worker.join();
  INFO(report.message);
  CHECK(worker_nice == expected);
  CHECK(report.ok == (expected == platform::kBackgroundWorkerNice));
  CHECK(platform::thread_nice() == main_before);
  // The workers' call does the same and says where it ended up.
  int background = -100;
  std::thread([&] { background = platform::become_background_thread(); }).join();
  CHECK(background == expected);
  CHECK(platform::thread_nice() == main_before);

  for (int bad : {-1, 20, -20}) {
    const platform::RealtimeReport r = platform::set_thread_nice(bad);
    CHECK_FALSE(r.ok);
    CHECK(r.message.find("outside 0..19") != std::string::npos);
  }
  CHECK(platform::thread_nice() == main_before);
}
