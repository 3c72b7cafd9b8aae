// `pwcontact screen`'s input: text parsed as particles (q or axes format) as
// the command line does, stored (a particle the store refuses is an
// error), screened in an open or periodic box, and the pairs compared with a
// brute-force scan by the reference path wherever mu^2 is clear of the
// cutoff and the forms are conditioned as the screen's guarantee says.
#include <cstdint>
#include <set>
#include <string_view>
#include <utility>

#include "cli/command_line.hpp"
#include "cli/number_table.hpp"
#include "fuzz_checks.hpp"

using namespace pwcontact;

namespace {

double form_condition(const double q[6]) { return fuzz::condition_at(q, q, 0); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const bool axes = data[0] & 1, periodic = data[0] & 2, with_mu2 = data[0] & 4;
  const double cutoff = 0.5 + (data[0] >> 3) / 16.0;
  const double length = 1 + data[1] / 8.0;
  const std::string_view text(reinterpret_cast<const char*>(data + 2), size - 2);
  cli::NumberColumns table;
  try {
    table = cli::parse_number_columns(text, axes ? 10 : 9, 1, true, "fuzz");
  } catch (const cli::CommandError&) {
    return 0;
  }
  const std::size_t n = std::min<std::size_t>(table.records(), 48);
  const auto& c = table.columns;
  ParticleStore particles;
  try {
    for (std::size_t i = 0; i < n; ++i) {
      if (axes)
        particles.add_axes({c[0][i], c[1][i], c[2][i]}, {c[3][i], c[4][i], c[5][i]},
                           {c[6][i], c[7][i], c[8][i], c[9][i]});
      else
        particles.add({c[0][i], c[1][i], c[2][i]},
                      {c[3][i], c[4][i], c[5][i], c[6][i], c[7][i], c[8][i]});
    }
  } catch (const std::invalid_argument&) {
    return 0;  // refused with a message: what a malformed scene gets
  }
  const Box box = periodic ? Box::periodic_box(length, length, length) : Box::open();
  ScreenOptions options;
  options.cutoff = cutoff;
  options.with_mu2 = with_mu2;
  options.threads = 1;
  ScreenedPairs pairs;
  try {
    screen_pairs(particles, box, options, pairs);
  } catch (const std::invalid_argument&) {
    return 0;  // a box too small, centres beyond the range: refused with a message
  }
  std::set<std::pair<std::uint32_t, std::uint32_t>> found;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    fuzz::expect(pairs.i[k] < pairs.j[k] && pairs.j[k] < n, "pairs i < j of the scene");
    if (k > 0)
      fuzz::expect(
          std::make_pair(pairs.i[k - 1], pairs.j[k - 1]) < std::make_pair(pairs.i[k], pairs.j[k]),
          "pairs sorted, each once");
    found.insert({pairs.i[k], pairs.j[k]});
  }
  const double cutoff2 = cutoff * cutoff;
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j) {
      double r[3], qi[6], qj[6];
      for (int a = 0; a < 3; ++a) {
        r[a] = particles.centre(a)[j] - particles.centre(a)[i];
        if (periodic) {
          r[a] =
              std::fmod(particles.centre(a)[j], length) - std::fmod(particles.centre(a)[i], length);
          r[a] -= length * std::nearbyint(r[a] / length);
        }
      }
      for (int a = 0; a < 6; ++a) qi[a] = particles.q(a)[i], qj[a] = particles.q(a)[j];
      if (form_condition(qi) > 1e8 || form_condition(qj) > 1e8) continue;
      const ContactResult<double> ref = contact_function<double>(r, qi, qj);
      if (ref.status != Status::ok && ref.status != Status::out_of_range) continue;
      const double cond = fuzz::condition_at(qi, qj, ref.lambda);
      const double band =
          std::max(1e-9, 32 * std::numeric_limits<double>::epsilon() * cond) * cutoff2 +
          16 * std::numeric_limits<double>::epsilon() * length * length;
      if (std::abs(ref.mu2 - cutoff2) <= band) continue;
      fuzz::expect(found.count({i, j}) == (ref.mu2 < cutoff2 ? 1u : 0u),
                   "the screen's pairs are the brute force's", double(i), double(j));
    }
  return 0;
}
