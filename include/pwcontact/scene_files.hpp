// Scenes as simulation programs write them: GSD files (HOOMD-blue's format)
// and LAMMPS data and dump files of atom_style ellipsoid, read into a
// ParticleStore and a Box for screen_pairs.
//
// Conventions (converted on reading): GSD gives semi-axes per type
// (particles/type_shapes: Ellipsoid a, b, c; Sphere diameter), orientations
// as quaternions (w, x, y, z), a periodic box [Lx, Ly, Lz, xy, xz, yz] with
// unitless tilts, and 2D scenes by configuration/dimensions = 2 (ellipses in
// the plane). LAMMPS gives shapes as diameters (shapex shapey shapez), tilts
// as lengths (xy xz yz), and a triclinic dump's box as its bounding box.
//
// Every reader throws std::invalid_argument for a malformed file (naming
// the file and the frame, line, particle or chunk) and std::runtime_error
// when the file cannot be read.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <unordered_map>
#include <vector>

#include "pwcontact/screen.hpp"

namespace pwcontact {

struct Scene {
  ParticleStore particles;
  Box box;                              // periodic as the file gives it
  std::vector<std::string> type_names;  // GSD particles/types, LAMMPS atom types
  std::vector<std::uint32_t> type_id;   // per particle, an index into type_names
  std::vector<std::uint64_t> id;        // LAMMPS atom ids (empty for GSD: the tags are 0 .. N-1)
  std::uint64_t frame = 0;              // the frame read
  std::uint64_t frames = 1;             // how many the file has
};

// Frame `frame` of a GSD file (negative: from the end, -1 the last), with
// the schema's defaults for chunks the frame lacks (from frame 0 when it has
// them for as many particles, else HOOMD's defaults).
Scene read_gsd(const std::string& path, std::int64_t frame = -1);

// A LAMMPS data file of atom_style ellipsoid: the header's box (with its
// tilts), the Atoms section (id type ellipsoidflag density x y z [ix iy
// iz]) and the Ellipsoids section (id shapex shapey shapez quatw quati
// quatj quatk). Particles in the order of the Atoms section.
Scene read_lammps_data(const std::string& path);

// Which columns of a dump's ITEM: ATOMS line hold what; empty names are
// looked for by their usual names (x y z or xu yu zu, shapex shapey shapez,
// quatw quati quatj quatk), and a compute's columns may be named instead,
// e.g. shape = {"c_s[1]", "c_s[2]", "c_s[3]"}.
struct LammpsColumns {
  std::string position[3];
  std::string shape[3];       // diameters
  std::string quaternion[4];  // w i j k
};

// Frame `frame` (negative: from the end) of a LAMMPS text dump (dump
// custom) with positions, shapes and quaternions per atom.
Scene read_lammps_dump(const std::string& path, std::int64_t frame = -1,
                       const LammpsColumns& columns = {});

// A GSD file (file layer 2.0, the hoomd schema) written frame by frame to a
// seekable stream: the chunks of a frame, end_frame(), ..., finish() (which
// writes the index and the names, and the header last). For scenes made in
// C++ and for results beside a scene. Throws std::invalid_argument for a
// chunk that does not fit its rows, std::runtime_error when the stream fails.
class GsdWriter {
 public:
  explicit GsdWriter(std::ostream& out);
  GsdWriter(const GsdWriter&) = delete;
  GsdWriter& operator=(const GsdWriter&) = delete;

  // `values` as `rows` rows of values.size() / rows columns.
  void write(const std::string& name, const std::vector<float>& values, std::uint64_t rows);
  void write(const std::string& name, const std::vector<double>& values, std::uint64_t rows);
  void write(const std::string& name, const std::vector<std::uint32_t>& values, std::uint64_t rows);
  void write(const std::string& name, const std::vector<std::uint64_t>& values, std::uint64_t rows);
  // One row per string, each zero-terminated in a row as long as the
  // longest (particles/types, particles/type_shapes).
  void write(const std::string& name, const std::vector<std::string>& rows);
  // Any chunk as the file layer stores it: `rows` x `columns` elements of
  // the specification's type code `type` (1 uint8 .. 10 float64, 11 char).
  void write_chunk(const std::string& name, std::uint8_t type, std::uint64_t rows,
                   std::uint32_t columns, const void* data);
  void end_frame();
  void finish();

 private:
  void write_raw(const std::string& name, std::uint8_t type, std::uint64_t rows,
                 std::uint64_t count, const void* data);
  struct Entry {
    std::uint64_t frame, rows;
    std::int64_t location;
    std::uint32_t columns;
    std::uint16_t id;
    std::uint8_t type;
  };
  std::ostream& out_;
  std::uint64_t frame_ = 0;
  std::int64_t end_ = 0;  // where the next chunk goes
  std::vector<Entry> index_;
  std::vector<std::string> names_;
  std::unordered_map<std::string, std::uint16_t> ids_;
  bool finished_ = false;
};

// Frame `frame` (negative: from the end) of the GSD file `input` written to
// `out` as a GSD file of one frame: every chunk the frame has or takes from
// frame 0, and `log/particles/<name>` with one value per particle, e.g. the
// overlap counts of pair_counts as log/particles/overlaps, which OVITO and
// python3-gsd read as a per-particle property. Throws as read_gsd does, and
// std::invalid_argument when the values are not one per particle.
void write_gsd_frame_with_values(const std::string& input, std::int64_t frame,
                                 const std::string& name, const std::vector<std::uint32_t>& values,
                                 std::ostream& out);

}  // namespace pwcontact
