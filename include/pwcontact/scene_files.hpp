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
#include <string>
#include <vector>

#include "pwcontact/screen.hpp"

namespace pwcontact {

struct Scene {
  ParticleStore particles;
  Box box;                                 // periodic as the file gives it
  std::vector<std::string> type_names;     // GSD particles/types, LAMMPS atom types
  std::vector<std::uint32_t> type_id;      // per particle, an index into type_names
  std::vector<std::uint64_t> id;           // LAMMPS atom ids (empty for GSD: the tags are 0 .. N-1)
  std::uint64_t frame = 0;                 // the frame read
  std::uint64_t frames = 1;                // how many the file has
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

}  // namespace pwcontact
