// A number as messages show it: the shortest of 15 or 17 significant digits
// that reads back as the same double ("1e-300", "0.1", "inf"), where
// std::to_string writes "0.000000" for 1e-300 and 309 digits for 1e308.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

namespace pwcontact::detail {

inline std::string number_text(double x) {
  char text[32];
  std::snprintf(text, sizeof text, "%.15g", x);
  if (std::strtod(text, nullptr) != x) std::snprintf(text, sizeof text, "%.17g", x);
  return text;
}

}  // namespace pwcontact::detail
