#include "configuration.hpp"

namespace pwcontact::bench {

const char* path_name(Path path) noexcept {
  switch (path) {
    case Path::scalar_reference: return "scalar_reference";
    case Path::brent_baseline: return "brent_baseline";
    case Path::batch_double: return "batch_double";
    case Path::batch_mixed: return "batch_mixed";
    case Path::batch_single: return "batch_single";
    case Path::batch_float: return "batch_float";
    case Path::overlap_double: return "overlap_double";
    case Path::overlap_mixed: return "overlap_mixed";
    case Path::overlap_single: return "overlap_single";
    case Path::overlap_float: return "overlap_float";
  }
  return "unknown";
}

const char* family_name(Family family) noexcept {
  switch (family) {
    case Family::random: return "random";
    case Family::pw85: return "pw85";
    case Family::extreme: return "extreme";
    case Family::scene: return "scene";
  }
  return "unknown";
}

Precision path_precision(Path path) noexcept {
  switch (path) {
    case Path::batch_mixed:
    case Path::overlap_mixed: return Precision::mixed;
    case Path::batch_single:
    case Path::overlap_single: return Precision::single_precision;
    case Path::batch_float:
    case Path::overlap_float: return Precision::automatic;
    default: return Precision::double_precision;
  }
}

const char* precision_label(Path path) noexcept {
  switch (path_precision(path)) {
    case Precision::mixed: return "mixed";
    case Precision::single_precision: return "float, double pairs";
    case Precision::automatic: return "float, float pairs";
    default: return "double";
  }
}

std::string Configuration::settings_name() const {
  std::string name = std::string(path_name(path)) + "/" + family_name(family);
  if (is_batch(path)) {
    name += std::string("/isa:") + isa_name(isa) + "/iterations:" + std::to_string(iterations);
    if (formulation != Formulation::automatic)
      name += std::string("/formulation:") + formulation_name(formulation);
    if (accuracy != Accuracy::standard) name += std::string("/accuracy:") + accuracy_name(accuracy);
  }
  return name;
}

std::string Configuration::name() const {
  return settings_name() + "/threads:" + std::to_string(threads);
}

BatchOptions Configuration::options() const {
  BatchOptions options;
  options.iterations = iterations;
  options.threads = threads;
  options.isa = isa;
  options.precision = path_precision(path);
  options.accuracy = accuracy;
  options.formulation = formulation;
  return options;
}

}  // namespace pwcontact::bench
