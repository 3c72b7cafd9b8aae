#include "command_line.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace pwcontact::bench {

std::optional<std::string> flag_value(const char* arg, const std::string& name) {
  const std::string prefix = "--" + name + "=";
  if (std::strncmp(arg, prefix.c_str(), prefix.size()) != 0) return std::nullopt;
  return std::string(arg + prefix.size());
}

long parse_count(const std::string& text, const std::string& flag, long minimum) {
  std::size_t used = 0;
  long value = 0;
  try {
    value = std::stol(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || value < minimum)
    throw std::invalid_argument("--" + flag + ": '" + text +
                                "' is not an integer >= " + std::to_string(minimum));
  return value;
}

std::vector<int> sorted_unique(std::vector<int> counts) {
  std::sort(counts.begin(), counts.end());
  counts.erase(std::unique(counts.begin(), counts.end()), counts.end());
  return counts;
}

std::vector<std::string> parse_names(const std::string& list, const std::string& flag) {
  std::vector<std::string> names;
  std::stringstream items(list);
  for (std::string item; std::getline(items, item, ',');)
    if (!item.empty()) names.push_back(item);
  if (names.empty()) throw std::invalid_argument("--" + flag + ": empty list");
  return names;
}

std::vector<int> parse_counts(const std::string& list, const std::string& flag, int minimum) {
  std::vector<int> counts;
  for (const std::string& item : parse_names(list, flag))
    counts.push_back(int(parse_count(item, flag, minimum)));
  return sorted_unique(std::move(counts));
}

double parse_positive(const std::string& text, const std::string& flag) {
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !(value > 0) || !std::isfinite(value))
    throw std::invalid_argument("--" + flag + ": '" + text + "' is not a positive number");
  return value;
}

}  // namespace pwcontact::bench
