// The summary `screen` and `demo` print: each stage of a screen with its
// counts and time, and the rates.
#pragma once

#include <string>

#include "pwcontact/screen.hpp"

namespace pwcontact::cli {

std::string describe_screen(const ScreenReport& report, const Box& box, double cutoff);

}  // namespace pwcontact::cli
