#include "configuration.hpp"

namespace pwcontact::bench {

const char* path_name(Path path) noexcept {
  switch (path) {
    case Path::scalar_reference: return "scalar_reference";
    case Path::brent_baseline: return "brent_baseline";
    case Path::batch_double: return "batch_double";
    case Path::batch_float: return "batch_float";
  }
  return "unknown";
}

const char* family_name(Family family) noexcept {
  switch (family) {
    case Family::random: return "random";
    case Family::pw85: return "pw85";
  }
  return "unknown";
}

std::string Configuration::name() const {
  std::string name = std::string(path_name(path)) + "/" + family_name(family);
  if (is_batch(path))
    name += std::string("/isa:") + isa_name(isa) + "/iterations:" + std::to_string(iterations);
  return name + "/threads:" + std::to_string(threads);
}

}  // namespace pwcontact::bench
