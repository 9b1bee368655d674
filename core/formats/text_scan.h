// Whitespace-separated tokens and locale-free numbers over a byte view, and
// the data lines of a line-based text file. Shared by the text parsers
// (ASCII PLY/STL, TUM, markers, scopetrack-register's pairs). Never
// allocates; tracks the line number for error messages.
#pragma once

#include <charconv>
#include <cstddef>
#include <string>
#include <string_view>

#include "core/base/result.h"

namespace st {

class TextScanner {
 public:
  explicit TextScanner(std::string_view text) : text_(text) {}

  // Next token (maximal run of non-whitespace) or empty at the end.
  std::string_view next_token() {
    skip_space();
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }
  // Skips the rest of the current line including its '\n'.
  void skip_line() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    if (pos_ < text_.size()) {
      ++pos_;
      ++line_;
    }
  }
  bool at_end() {
    skip_space();
    return pos_ >= text_.size();
  }
  int line() const { return line_; }
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return text_.size() - pos_; }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }
  void skip_space() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  std::string_view text_;
  std::size_t pos_ = 0;
  int line_ = 1;
};

// Whole-token decimal number ("1", "-2.5e3", "+4"); false on junk, empty,
// or out of range. NaN/inf parse (from_chars accepts them): callers that
// need finite values check std::isfinite.
inline bool parse_double(std::string_view tok, double* out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  const auto [end, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  return ec == std::errc() && end == tok.data() + tok.size();
}

inline bool parse_int64(std::string_view tok, long long* out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  const auto [end, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  return ec == std::errc() && end == tok.data() + tok.size();
}

// The same, and within [lo, hi] (command-line values); the output is
// written only on success.
inline bool parse_int64_in(std::string_view tok, long long lo, long long hi, long long* out) {
  long long v = 0;
  if (!parse_int64(tok, &v) || v < lo || v > hi) return false;
  *out = v;
  return true;
}

// parse_double, and within [lo, hi] (NaN fails the range); the output is
// written only on success.
inline bool parse_double_in(std::string_view tok, double lo, double hi, double* out) {
  double v = 0;
  if (!parse_double(tok, &v) || !(v >= lo && v <= hi)) return false;
  *out = v;
  return true;
}

// A short, printable excerpt of untrusted bytes for an error message.
inline std::string quote_bytes(std::string_view s, std::size_t max_chars = 40) {
  std::string out = "'";
  for (char c : s.substr(0, max_chars)) out += (c >= 32 && c < 127) ? c : '?';
  if (s.size() > max_chars) out += "...";
  return out + "'";
}

// Splits text into lines (numbered from 1), skipping blank ones and those
// whose first non-blank character is '#'; calls fn(line, number) for the
// others and stops at the first error fn returns.
template <class Fn>
Status for_each_data_line(std::string_view text, Fn&& fn) {
  int number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    const std::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++number;
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string_view::npos || line[first] == '#') continue;
    if (Status s = fn(line, number); !s) return s;
  }
  return Status::Ok();
}

}  // namespace st
