// Numbers and input text as messages show them.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

namespace pwcontact::detail {

// A number: the shortest of 15 or 17 significant digits that reads back as
// the same double ("1e-300", "0.1", "inf"), where std::to_string writes
// "0.000000" for 1e-300 and 309 digits for 1e308.
inline std::string number_text(double x) {
  char text[32];
  std::snprintf(text, sizeof text, "%.15g", x);
  if (std::strtod(text, nullptr) != x) std::snprintf(text, sizeof text, "%.17g", x);
  return text;
}

// Text read from a file: bytes that are not printable ASCII as \xHH (a NUL
// would cut the message short, an escape sequence act on the terminal).
inline std::string printable(std::string_view text) {
  std::string out;
  for (const char c : text) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      out += c;
    } else {
      char escaped[5];
      std::snprintf(escaped, sizeof escaped, "\\x%02X", u);
      out += escaped;
    }
  }
  return out;
}

}  // namespace pwcontact::detail
