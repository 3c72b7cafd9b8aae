// Reading the benchmarks' own command-line flags, "--name=value".
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace pwcontact::bench {

// "--name=value" -> value; nullopt when `arg` is another flag.
std::optional<std::string> flag_value(const char* arg, const std::string& name);

// An integer >= minimum; std::invalid_argument naming `flag` otherwise.
long parse_count(const std::string& text, const std::string& flag, long minimum);

// "2,3,4" -> {2, 3, 4}, sorted, without repeats; each >= minimum.
std::vector<int> parse_counts(const std::string& list, const std::string& flag, int minimum);

// A positive finite number; std::invalid_argument naming `flag` otherwise.
double parse_positive(const std::string& text, const std::string& flag);

// "a,b,c" -> {"a", "b", "c"}; std::invalid_argument naming `flag` when empty.
std::vector<std::string> parse_names(const std::string& list, const std::string& flag);

std::vector<int> sorted_unique(std::vector<int> counts);

}  // namespace pwcontact::bench
