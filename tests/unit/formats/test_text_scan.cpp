// core/formats/text_scan.h's range parsers for command-line values: the whole token
// must be a number inside the range; anything else is refused.
#include <doctest/doctest.h>

#include <cmath>

#include "core/formats/text_scan.h"

using namespace st;

TEST_CASE("text_scan: whole numbers in a range, bad tokens refused") {
  long long v = -7;
  CHECK(parse_int64_in("3", 1, 1000, &v));
  CHECK(v == 3);
  CHECK(parse_int64_in("+1000", 1, 1000, &v));
  CHECK(v == 1000);
  for (const char* bad : {"", "0", "1001", "-1", "3x", "x3", " 5", "5 ", "1e2", "2.0", "+", "-", "0x10",
                          "99999999999999999999"}) {
    CAPTURE(bad);
    v = -7;
    CHECK_FALSE(parse_int64_in(bad, 1, 1000, &v));
    CHECK(v == -7);  // untouched on refusal
  }
}

TEST_CASE("text_scan: real numbers in a range, NaN and bad tokens refused") {
  double v = -7;
  CHECK(parse_double_in("0.5", 0.0, 1.0, &v));
  CHECK(v == 0.5);
  CHECK(parse_double_in("1e-1", 0.0, 1.0, &v));
  CHECK(v == doctest::Approx(0.1));
  for (const char* bad : {"", "nan", "NaN", "inf", "-0.1", "1.5", "0.5x", "1e", " 0.5", ",5", "+"}) {
    CAPTURE(bad);
    v = -7;
    CHECK_FALSE(parse_double_in(bad, 0.0, 1.0, &v));
    CHECK(v == -7);
  }
}
