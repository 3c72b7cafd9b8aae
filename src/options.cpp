// Names of the batch options, as the command line and reports spell them.
#include <initializer_list>

#include "pwcontact/batch.hpp"

namespace pwcontact {
namespace {

template <class E>
std::optional<E> parse_named(std::string_view name, std::initializer_list<E> values,
                             const char* (*name_of)(E) noexcept) {
  for (E value : values)
    if (name == name_of(value)) return value;
  return std::nullopt;
}

}  // namespace

const char* precision_name(Precision p) noexcept {
  switch (p) {
    case Precision::automatic: return "auto";
    case Precision::double_precision: return "double";
    case Precision::single_precision: return "float";
    case Precision::mixed: return "mixed";
  }
  return "unknown";
}

const char* accuracy_name(Accuracy a) noexcept {
  switch (a) {
    case Accuracy::standard: return "standard";
    case Accuracy::high: return "high";
  }
  return "unknown";
}

const char* formulation_name(Formulation f) noexcept {
  switch (f) {
    case Formulation::automatic: return "auto";
    case Formulation::newton: return "newton";
    case Formulation::log_odds: return "log_odds";
  }
  return "unknown";
}

std::optional<Precision> parse_precision(std::string_view name) noexcept {
  return parse_named(name,
                     {Precision::automatic, Precision::double_precision,
                      Precision::single_precision, Precision::mixed},
                     precision_name);
}

std::optional<Accuracy> parse_accuracy(std::string_view name) noexcept {
  return parse_named(name, {Accuracy::standard, Accuracy::high}, accuracy_name);
}

std::optional<Formulation> parse_formulation(std::string_view name) noexcept {
  return parse_named(name, {Formulation::automatic, Formulation::newton, Formulation::log_odds},
                     formulation_name);
}

}  // namespace pwcontact
