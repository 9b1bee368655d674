// The replay's building blocks: the SPSC queue and the latency histogram.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <thread>
#include <vector>

#include "core/base/latency_histogram.h"
#include "platform/spsc_queue.h"
#include "support/alloc_guard.h"

using namespace st;

TEST_CASE("app_queue: spsc queue refuses when full, returns items in order, wraps around") {
  platform::SpscQueue<int, 4> q;
  int v = -1;
  CHECK_FALSE(q.try_pop(&v));
  for (int round = 0; round < 5; ++round) {  // indices wrap many times
    for (int i = 0; i < 4; ++i) CHECK(q.try_push(round * 10 + i));
    CHECK_FALSE(q.try_push(99));
    CHECK(q.size() == 4);
    for (int i = 0; i < 4; ++i) {
      REQUIRE(q.try_pop(&v));
      CHECK(v == round * 10 + i);
    }
    CHECK_FALSE(q.try_pop(&v));
  }
}

TEST_CASE("app_queue: spsc queue hands 200000 items between two threads in order, no allocation") {
  constexpr int kItems = 200000;
  auto q = std::make_unique<platform::SpscQueue<std::uint64_t, 64>>();
  std::uint64_t producer_allocs = 1, stalls = 0;
  std::thread producer([&] {
    test::AllocationCounter allocs;
    for (std::uint64_t i = 0; i < kItems; ++i) stalls += q->push_wait(i * 3 + 1) ? 1 : 0;
    producer_allocs = allocs.count();
  });
  test::AllocationCounter allocs;
  bool in_order = true;
  for (std::uint64_t i = 0; i < kItems; ++i) {
    std::uint64_t v = 0;
    q->pop_wait(&v);
    in_order = in_order && v == i * 3 + 1;
  }
  const std::uint64_t consumer_allocs = allocs.count();
  producer.join();
  CHECK(in_order);
  CHECK(consumer_allocs == 0);
  CHECK(producer_allocs == 0);
  CHECK(q->size() == 0);
  MESSAGE("producer waited on a full queue " << stalls << " times");
}

TEST_CASE("app_queue: latency histogram quantiles within one bin of the sorted samples") {
  std::mt19937 rng(7);
  std::lognormal_distribution<double> dist(1.5, 0.6);  // ms, a long right tail
  LatencyHistogram h;
  std::vector<double> v;
  for (int i = 0; i < 20000; ++i) {
    v.push_back(dist(rng));
    h.add(v.back());
  }
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (double x : v) sum += x;
  CHECK(h.count() == 20000);
  CHECK(h.mean_ms() == doctest::Approx(sum / 20000).epsilon(1e-9));
  CHECK(h.max_ms() == v.back());
  for (double q : {0.5, 0.9, 0.99, 0.999}) {
    const double exact = v[static_cast<std::size_t>(std::ceil(q * 20000)) - 1];
    CHECK(h.quantile_ms(q) >= exact);
    CHECK(h.quantile_ms(q) <= exact + LatencyHistogram::kBinMs + 1e-12);
  }
}

TEST_CASE("app_queue: latency histogram handles empty, overflow, negative and NaN values") {
  LatencyHistogram h;
  CHECK(h.quantile_ms(0.99) == 0.0);
  CHECK(h.mean_ms() == 0.0);
  h.add(-3.0);
  h.add(std::nan(""));
  CHECK(h.count() == 2);
  CHECK(h.quantile_ms(1.0) == 0.0);
  h.clear();
  for (int i = 0; i < 98; ++i) h.add(1.0);
  h.add(900.0);   // beyond the last bin
  h.add(1200.0);
  CHECK(h.quantile_ms(0.5) == doctest::Approx(1.01));
  CHECK(h.quantile_ms(0.99) == 1200.0);  // past the bins: the maximum
  CHECK(h.max_ms() == 1200.0);
  CHECK(h.mean_ms() == doctest::Approx((98.0 + 2100.0) / 100.0));
  test::AllocationCounter allocs;
  for (int i = 0; i < 1000; ++i) h.add(i * 0.37);
  CHECK(allocs.count() == 0);
}
