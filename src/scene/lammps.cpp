// LAMMPS scenes of atom_style ellipsoid: data files (read_data's format)
// and text dumps (dump custom), per the LAMMPS documentation of both.
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "number_text.hpp"
#include "pwcontact/scene_files.hpp"
#include "scene/shape_json.hpp"

namespace pwcontact {
namespace {

class Lines {
 public:
  explicit Lines(const std::string& path) : path_(path), in_(path, std::ios::binary) {
    if (!in_) throw std::runtime_error("cannot open " + path);
  }
  // The next line without its comment ('#' on) and trailing blanks; false at the end.
  bool next(std::string& line) {
    if (!std::getline(in_, line)) {
      if (in_.bad()) throw std::runtime_error("cannot read " + path_);
      return false;
    }
    ++number_;
    if (const std::size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    while (!line.empty() && (line.back() == ' ' || line.back() == '\t' || line.back() == '\r'))
      line.pop_back();
    return true;
  }
  std::size_t number() const { return number_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument(path_ + ":" + std::to_string(number_) + ": " + what);
  }
  std::istream& stream() { return in_; }
  void set_number(std::size_t n) { number_ = n; }
  // The bytes after the current position (0 when it is unknown).
  std::uint64_t bytes_left() {
    const std::streampos at = in_.tellg();
    if (at < 0) return 0;
    in_.seekg(0, std::ios::end);
    const std::streampos end = in_.tellg();
    in_.seekg(at);
    return end > at ? std::uint64_t(end - at) : 0;
  }

 private:
  std::string path_;
  std::ifstream in_;
  std::size_t number_ = 0;
};

std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t at = 0;
  while (at < line.size()) {
    while (at < line.size() && (line[at] == ' ' || line[at] == '\t')) ++at;
    const std::size_t start = at;
    while (at < line.size() && line[at] != ' ' && line[at] != '\t') ++at;
    if (at > start) out.push_back(line.substr(start, at - start));
  }
  return out;
}

// (A '+' is taken before a number as LAMMPS takes it, but not before a
// sign: "+-1.5" was read as -1.5.)
std::string_view without_plus(std::string_view word) {
  if (word.size() > 1 && word[0] == '+' && word[1] != '-' && word[1] != '+') word.remove_prefix(1);
  return word;
}

double number(std::string_view given, const Lines& lines, const char* what) {
  double value = 0;
  const std::string_view word = without_plus(given);
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size() || !std::isfinite(value))
    lines.fail(std::string(what) + " '" + detail::printable(given) + "' is not a finite number");
  return value;
}

std::uint64_t whole(std::string_view word, const Lines& lines, const char* what) {
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size())
    lines.fail(std::string(what) + " '" + detail::printable(word) + "' is not a whole number");
  return value;
}

std::int64_t integer(std::string_view given, const Lines& lines, const char* what) {
  std::int64_t value = 0;
  const std::string_view word = without_plus(given);
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (error != std::errc() || end != word.data() + word.size())
    lines.fail(std::string(what) + " '" + detail::printable(given) + "' is not an integer");
  return value;
}

bool starts_section(const std::string& line) {
  const std::vector<std::string_view> w = words(line);
  return !w.empty() && ((w[0][0] >= 'A' && w[0][0] <= 'Z') || (w[0][0] >= 'a' && w[0][0] <= 'z'));
}

// The header lines a data file's scene is read from, known by their last
// words (LAMMPS's keywords): their kind, how many numbers come before the
// keywords, and for the box's bounds the axis.
constexpr const char* bound_names[3][2] = {{"xlo", "xhi"}, {"ylo", "yhi"}, {"zlo", "zhi"}};

struct HeaderKeyword {
  enum Kind { atoms, ellipsoids, atom_types, tilts, bounds } kind = atoms;
  const char* name = nullptr;  // null: not one of these lines
  int words = 0, numbers = 0, axis = 0;
};

bool same_letters(std::string_view a, std::string_view b, bool any_case) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const char x = a[k], y = b[k];
    const auto lower = [](char c) { return c >= 'A' && c <= 'Z' ? char(c - 'A' + 'a') : c; };
    if (any_case ? lower(x) != lower(y) : x != y) return false;
  }
  return true;
}

// Which of the header lines `w` is (a line whose keywords are written in
// another case is refused, naming it).
HeaderKeyword header_keyword(const std::vector<std::string_view>& w, const Lines& lines) {
  struct Known {
    HeaderKeyword::Kind kind;
    const char* name;
    std::vector<std::string_view> keywords;
    int numbers, axis;
  };
  static const Known known[] = {
      {HeaderKeyword::atoms, "atoms", {"atoms"}, 1, 0},
      {HeaderKeyword::ellipsoids, "ellipsoids", {"ellipsoids"}, 1, 0},
      {HeaderKeyword::atom_types, "atom types", {"atom", "types"}, 1, 0},
      {HeaderKeyword::tilts, "xy xz yz", {"xy", "xz", "yz"}, 3, 0},
      {HeaderKeyword::bounds, "xlo xhi", {"xlo", "xhi"}, 2, 0},
      {HeaderKeyword::bounds, "ylo yhi", {"ylo", "yhi"}, 2, 1},
      {HeaderKeyword::bounds, "zlo zhi", {"zlo", "zhi"}, 2, 2},
  };
  for (const Known& k : known) {
    const std::size_t n = k.keywords.size();
    if (w.size() < n) continue;
    bool exact = true, any_case = true;
    for (std::size_t j = 0; j < n; ++j) {
      const std::string_view word = w[w.size() - n + j];
      exact = exact && same_letters(word, k.keywords[j], false);
      any_case = any_case && same_letters(word, k.keywords[j], true);
    }
    // ("Atoms" alone is the section's name, not the count's keyword.)
    if (!exact && any_case && w.size() > n)
      lines.fail(std::string("the header keywords '") + k.name +
                 "' are written in another case (LAMMPS's are lower case)");
    if (exact) return {k.kind, k.name, int(n), k.numbers, k.axis};
  }
  return {};
}

// A particle of a LAMMPS scene before it is stored.
struct Atom {
  std::uint64_t id;
  std::uint32_t type;
  std::array<double, 3> position;
  std::array<double, 3> diameters;
  std::array<double, 4> quaternion;
  std::size_t line;        // where its shape is given (0: not yet)
  std::size_t atoms_line;  // a data file's Atoms line
};

// `where` follows the line number in messages (": frame 3", or empty), as
// in the dump reader's own messages ("file:12: frame 3: ...").
Scene store(std::vector<Atom>& atoms, const Box& box, std::uint32_t types, const std::string& path,
            const std::string& where) {
  Scene scene;
  scene.box = box;
  for (std::uint32_t t = 1; t <= types; ++t) scene.type_names.push_back(std::to_string(t));
  scene.particles.resize(atoms.size());
  for (std::size_t i = 0; i < atoms.size(); ++i) {
    const Atom& a = atoms[i];
    try {
      scene.particles.set_axes(i, a.position,
                               {a.diameters[0] / 2, a.diameters[1] / 2, a.diameters[2] / 2},
                               a.quaternion);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(path + ":" + std::to_string(a.line) + where + ": atom " +
                                  std::to_string(a.id) + ": " + detail::store_message(e, i));
    }
    scene.id.push_back(a.id);
    scene.type_id.push_back(a.type >= 1 ? a.type - 1 : 0);
  }
  return scene;
}

}  // namespace

Scene read_lammps_data(const std::string& path) {
  Lines lines(path);
  std::string line;
  lines.next(line);  // the title line
  std::uint64_t atoms_count = 0, ellipsoids_count = 0;
  std::uint32_t types = 1;
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0}, tilt[3] = {0, 0, 0};
  bool have[3] = {false, false, false};
  // Header: until the first section. A line is known by its keywords, its
  // last words, before anything else: a line of the box or a count that
  // begins with a word (nan, inf, a typo) is refused for it, not taken for
  // the name of a section (which skipped it: a tilt line so written left
  // the box orthogonal), and so is one with a number missing or too many.
  // Keywords in another case are refused as LAMMPS refuses them. Other
  // header lines (bonds, angles, their types, ...) are not needed here and
  // are passed over.
  while (lines.next(line)) {
    const std::vector<std::string_view> w = words(line);
    if (w.empty()) continue;
    const HeaderKeyword key = header_keyword(w, lines);
    if (!key.name && starts_section(line)) break;
    if (!key.name) continue;
    if (w.size() != std::size_t(key.numbers + key.words))
      lines.fail(std::string("a header line '") + key.name + "' has " +
                 std::to_string(key.numbers) + (key.numbers == 1 ? " number" : " numbers") +
                 " before its keywords, this one " + std::to_string(int(w.size()) - key.words));
    switch (key.kind) {
      case HeaderKeyword::atoms: atoms_count = whole(w[0], lines, "the atom count"); break;
      case HeaderKeyword::ellipsoids:
        ellipsoids_count = whole(w[0], lines, "the ellipsoid count");
        break;
      case HeaderKeyword::atom_types:
        types = std::uint32_t(whole(w[0], lines, "the atom type count"));
        break;
      case HeaderKeyword::tilts:
        for (int k = 0; k < 3; ++k) tilt[k] = number(w[std::size_t(k)], lines, "a tilt");
        break;
      case HeaderKeyword::bounds: {
        const int k = key.axis;
        lo[k] = number(w[0], lines, bound_names[k][0]);
        hi[k] = number(w[1], lines, bound_names[k][1]);
        have[k] = true;
        break;
      }
    }
  }
  for (int k = 0; k < 3; ++k)
    if (!have[k])
      lines.fail(std::string("the header gives no ") + "xyz"[k] + "lo " + "xyz"[k] + "hi line");
  Box box;
  try {
    box = Box::from_lammps(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], tilt[0], tilt[1], tilt[2]);
  } catch (const std::invalid_argument& e) {
    lines.fail(std::string("the box: ") + e.what());
  }

  std::vector<Atom> atoms;
  std::unordered_map<std::uint64_t, std::size_t> by_id;
  std::size_t shaped = 0;
  // Sections: a name line, then data lines until the next name. (The
  // header loop stopped on the first name, or at the end.)
  while (starts_section(line)) {
    const std::string section = std::string(words(line)[0]);
    const bool atoms_section = section == "Atoms", ellipsoids_section = section == "Ellipsoids";
    bool more = false;
    while ((more = lines.next(line)) && !starts_section(line)) {
      const std::vector<std::string_view> w = words(line);
      if (w.empty()) continue;
      if (atoms_section) {
        if (w.size() != 7 && w.size() != 10)
          lines.fail(
              "an Atoms line of atom_style ellipsoid has 7 or 10 fields (id type "
              "ellipsoidflag density x y z [ix iy iz]), this one " +
              std::to_string(w.size()));
        // Every field is read and checked as LAMMPS's read_data does
        // (positive ids, ellipsoidflag 0 or 1, positive density, integer
        // image flags), though only the id, type and position are kept.
        Atom a{};
        a.id = whole(w[0], lines, "the atom id");
        if (a.id == 0) lines.fail("atom id 0: LAMMPS atom ids are positive");
        a.type = std::uint32_t(whole(w[1], lines, "the atom type"));
        if (a.type < 1 || a.type > types)
          lines.fail("atom type " + std::to_string(a.type) + " is not one of the " +
                     std::to_string(types));
        const std::uint64_t flag = whole(w[2], lines, "the ellipsoid flag");
        if (flag == 0)
          lines.fail("atom " + std::to_string(a.id) +
                     " has ellipsoidflag 0: a point particle, no shape");
        if (flag != 1)
          lines.fail("atom " + std::to_string(a.id) + " has ellipsoidflag " +
                     detail::printable(w[2]) + ", not 0 or 1");
        const double density = number(w[3], lines, "the density");
        if (!(density > 0))
          lines.fail("atom " + std::to_string(a.id) + " has density " + detail::printable(w[3]) +
                     ": LAMMPS requires a positive density");
        for (int k = 0; k < 3; ++k)
          a.position[k] = number(w[std::size_t(4 + k)], lines, "a coordinate");
        for (std::size_t k = 7; k < w.size(); ++k) integer(w[k], lines, "the image flag");
        a.atoms_line = lines.number();
        if (!by_id.emplace(a.id, atoms.size()).second)
          lines.fail("atom id " + std::to_string(a.id) + " appears twice");
        atoms.push_back(a);
      } else if (ellipsoids_section) {
        if (w.size() != 8)
          lines.fail(
              "an Ellipsoids line has 8 fields (id shapex shapey shapez quatw quati quatj "
              "quatk), this one " +
              std::to_string(w.size()));
        const std::uint64_t id = whole(w[0], lines, "the atom id");
        const auto found = by_id.find(id);
        if (found == by_id.end())
          lines.fail("ellipsoid of atom " + std::to_string(id) +
                     ", which the Atoms section has not listed");
        Atom& a = atoms[found->second];
        if (a.line != 0)
          lines.fail("atom " + std::to_string(id) +
                     " has a second Ellipsoids line (the first is line " + std::to_string(a.line) +
                     ")");
        for (int k = 0; k < 3; ++k)
          a.diameters[k] = number(w[std::size_t(1 + k)], lines, "a shape");
        for (int k = 0; k < 4; ++k)
          a.quaternion[k] = number(w[std::size_t(4 + k)], lines, "a quaternion component");
        a.line = lines.number();
        ++shaped;
      }
    }
    if (!more) break;
  }
  if (atoms.size() != atoms_count)
    throw std::invalid_argument(path + ": the header gives " + std::to_string(atoms_count) +
                                " atoms, the Atoms section " + std::to_string(atoms.size()));
  // An atom without a shape is named with its Atoms line (the section's
  // lines are one per atom, so the count alone would not say which).
  for (const Atom& a : atoms)
    if (a.line == 0)
      throw std::invalid_argument(path + ":" + std::to_string(a.atoms_line) + ": atom " +
                                  std::to_string(a.id) +
                                  " has no Ellipsoids line: every atom needs a shape");
  if (shaped != atoms.size() || ellipsoids_count != atoms.size())
    throw std::invalid_argument(path + ": " + std::to_string(atoms.size()) + " atoms but " +
                                std::to_string(shaped) + " Ellipsoids lines (header: " +
                                std::to_string(ellipsoids_count) + "): every atom needs a shape");
  return store(atoms, box, types, path, "");
}

Scene read_lammps_dump(const std::string& path, std::int64_t frame, const LammpsColumns& columns) {
  // A dump is read twice (where its frames start, then the one asked for):
  // from a pipe the second read hung or found nothing.
  struct stat info {};
  if (stat(path.c_str(), &info) == 0 && !S_ISREG(info.st_mode))
    throw std::invalid_argument(path +
                                ": not a regular file (a pipe or a device?): a LAMMPS dump is "
                                "read twice, its frames found and then one read, so from a file");
  // First pass: where each frame (ITEM: TIMESTEP) starts.
  std::vector<std::streampos> starts;
  std::vector<std::size_t> start_lines;
  {
    Lines lines(path);
    std::string line;
    for (std::streampos at = lines.stream().tellg(); lines.next(line); at = lines.stream().tellg())
      if (line.rfind("ITEM: TIMESTEP", 0) == 0) {
        starts.push_back(at);
        start_lines.push_back(lines.number());
      }
  }
  const std::int64_t count = std::int64_t(starts.size());
  if (count == 0) throw std::invalid_argument(path + ": no ITEM: TIMESTEP: not a LAMMPS dump");
  if (frame < -count || frame >= count)
    throw std::invalid_argument(path + ": frame " + std::to_string(frame) +
                                " is not in the file (it has " + std::to_string(count) +
                                " frames)");
  const std::size_t f = std::size_t(frame < 0 ? count + frame : frame);
  Lines lines(path);
  lines.stream().seekg(starts[f]);
  lines.set_number(start_lines[f] - 1);
  std::string line;
  const std::string frame_name = "frame " + std::to_string(f) + ": ";
  lines.next(line);  // ITEM: TIMESTEP
  lines.next(line);  // the step
  std::uint64_t atoms_count = 0;
  bool counted = false;
  double bound[3][3] = {};  // lo, hi, tilt per axis
  bool triclinic = false, periodic = true, open = true;
  std::vector<std::string> names;
  while (lines.next(line)) {
    if (line.rfind("ITEM: NUMBER OF ATOMS", 0) == 0) {
      if (!lines.next(line)) lines.fail("the dump ends after ITEM: NUMBER OF ATOMS");
      const auto w = words(line);
      if (w.size() != 1) lines.fail("expected the number of atoms");
      atoms_count = whole(w[0], lines, "the number of atoms");
      counted = true;
    } else if (line.rfind("ITEM: BOX BOUNDS", 0) == 0) {
      const auto w = words(line);
      triclinic = w.size() >= 6 && w[3] == "xy";
      for (std::size_t k = triclinic ? 6 : 3; k < w.size(); ++k) {
        periodic = periodic && w[k] == "pp";
        open = open && w[k] != "pp";
      }
      for (int k = 0; k < 3; ++k) {
        if (!lines.next(line)) lines.fail("the dump ends inside ITEM: BOX BOUNDS");
        const auto b = words(line);
        if (b.size() != (triclinic ? 3u : 2u))
          lines.fail(std::string("a box bounds line has ") + (triclinic ? "3" : "2") + " numbers");
        for (std::size_t j = 0; j < b.size(); ++j) bound[k][j] = number(b[j], lines, "a box bound");
      }
    } else if (line.rfind("ITEM: ATOMS", 0) == 0) {
      // (Without the count the frame's end is not known.)
      if (!counted) lines.fail(frame_name + "no ITEM: NUMBER OF ATOMS before ITEM: ATOMS");
      for (std::string_view w : words(std::string_view(line).substr(11))) names.emplace_back(w);
      break;
    } else if (line.rfind("ITEM: TIMESTEP", 0) == 0) {
      lines.fail("the frame has no ITEM: ATOMS");
    }
  }
  if (names.empty()) lines.fail("the frame has no ITEM: ATOMS line with column names");
  if (!periodic && !open)
    lines.fail("boundaries periodic along some axes and not others: not supported");
  // A triclinic dump gives the bounding box: the box's own bounds are
  // xlo = xlo_bound - min(0, xy, xz, xy + xz), xhi = xhi_bound - max(...),
  // ylo = ylo_bound - min(0, yz), yhi = yhi_bound - max(0, yz).
  double xy = 0, xz = 0, yz = 0;
  if (triclinic) {
    xy = bound[0][2];
    xz = bound[1][2];
    yz = bound[2][2];
    bound[0][0] -= std::min({0.0, xy, xz, xy + xz});
    bound[0][1] -= std::max({0.0, xy, xz, xy + xz});
    bound[1][0] -= std::min(0.0, yz);
    bound[1][1] -= std::max(0.0, yz);
  }
  Box box = Box::open();
  if (periodic) {
    try {
      box = Box::from_lammps(bound[0][1] - bound[0][0], bound[1][1] - bound[1][0],
                             bound[2][1] - bound[2][0], xy, xz, yz);
    } catch (const std::invalid_argument& e) {
      lines.fail(std::string("the box: ") + e.what());
    }
  }
  auto column = [&](const std::string& given, std::initializer_list<const char*> usual,
                    const char* what) -> std::size_t {
    std::vector<std::string> candidates;
    if (!given.empty())
      candidates.push_back(given);
    else
      for (const char* u : usual) candidates.emplace_back(u);
    for (const std::string& c : candidates)
      for (std::size_t k = 0; k < names.size(); ++k)
        if (names[k] == c) return k;
    std::string listed;
    for (const std::string& c : candidates) listed += (listed.empty() ? "" : " or ") + c;
    lines.fail(std::string("no column ") + listed + " (" + what + ") in ITEM: ATOMS");
  };
  const char* axes[3] = {"x", "y", "z"};
  std::size_t position[3], shape[3], quaternion[4], id_column = names.size(),
                                                    type_column = names.size();
  for (int k = 0; k < 3; ++k) {
    const std::string wrapped = axes[k], unwrapped = std::string(axes[k]) + "u";
    position[k] = column(columns.position[k], {wrapped.c_str(), unwrapped.c_str()}, "a position");
    // LAMMPS's scaled coordinates (xs, xsu, ...) are fractions of the box:
    // read as lengths they would place every particle within a unit of the
    // origin. Mapped explicitly, they are refused, not misread.
    const std::string& name = names[position[k]];
    if (name == std::string(axes[k]) + "s" || name == std::string(axes[k]) + "su")
      lines.fail("column " + detail::printable(name) +
                 " holds scaled coordinates (fractions of the box), which are not read: dump " +
                 wrapped + " or " + unwrapped + " (--columns " + wrapped + "=...)");
    const std::string usual_shape = std::string("shape") + axes[k];
    shape[k] = column(columns.shape[k], {usual_shape.c_str()}, "a shape, a diameter");
  }
  const char* quaternion_names[4] = {"quatw", "quati", "quatj", "quatk"};
  for (int k = 0; k < 4; ++k)
    quaternion[k] = column(columns.quaternion[k], {quaternion_names[k]}, "a quaternion component");
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (names[k] == "id") id_column = k;
    if (names[k] == "type") type_column = k;
  }
  // No more is reserved than the rest of the file could hold (a line of
  // names.size() columns has at least 2 names.size() bytes): a count of
  // 10^18 is then refused where the frame's lines end.
  const std::uint64_t room = lines.bytes_left() / (2 * names.size());
  std::vector<Atom> atoms;
  atoms.reserve(std::size_t(std::min(atoms_count, room)));
  std::unordered_map<std::uint64_t, std::size_t> line_of_id;
  line_of_id.reserve(std::size_t(std::min(atoms_count, room)));
  std::uint32_t types = 1;
  for (std::uint64_t n = 0; n < atoms_count; ++n) {
    if (!lines.next(line) || line.rfind("ITEM:", 0) == 0)
      lines.fail(frame_name + "the frame ends after " + std::to_string(n) + " of its " +
                 std::to_string(atoms_count) + " atoms");
    const auto w = words(line);
    if (w.size() != names.size())
      lines.fail("expected " + std::to_string(names.size()) + " columns, found " +
                 std::to_string(w.size()));
    Atom a{};
    a.id = id_column < w.size() ? whole(w[id_column], lines, "the atom id") : n + 1;
    a.type =
        type_column < w.size() ? std::uint32_t(whole(w[type_column], lines, "the atom type")) : 1;
    types = std::max(types, a.type);
    for (int k = 0; k < 3; ++k) {
      a.position[k] = number(w[position[k]], lines, "a coordinate");
      a.diameters[k] = number(w[shape[k]], lines, "a shape");
    }
    for (int k = 0; k < 4; ++k)
      a.quaternion[k] = number(w[quaternion[k]], lines, "a quaternion component");
    a.line = lines.number();
    if (const auto [at, added] = line_of_id.emplace(a.id, a.line); !added)
      lines.fail(frame_name + "atom id " + std::to_string(a.id) + " appears twice (first on line " +
                 std::to_string(at->second) + ")");
    atoms.push_back(a);
  }
  // The count's lines end the frame: what follows is the next frame's
  // ITEM: line or the end of the file (blank lines aside), not more atoms.
  bool more = false;
  while ((more = lines.next(line)) && line.find_first_not_of(" \t") == std::string::npos) {
  }
  if (more && line.rfind("ITEM:", 0) != 0)
    lines.fail(frame_name + "more atom lines than ITEM: NUMBER OF ATOMS gives (" +
               std::to_string(atoms_count) + ")");
  Scene scene = store(atoms, box, types, path, ": frame " + std::to_string(f));
  scene.frame = f;
  scene.frames = std::uint64_t(count);
  return scene;
}

}  // namespace pwcontact
