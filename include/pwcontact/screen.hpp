// Screening a scene: from N ellipsoids in a box to every pair (i < j) with
// mu < mu_cut (mu_cut = 1: the overlapping pairs; mu_cut > 1: a neighbour
// list with a skin), built on the batch path.
//
// Pipeline (screen_pairs):
//  1. candidates from cell lists, one per size class of bounding radius, so
//     that a polydisperse scene does not make every cell as large as the
//     largest particle's reach;
//  2. prefilters: |r| >= mu_cut (R_i + R_j) => out, the projections of the
//     scaled ellipsoids on r apart => out, |r| < mu_cut (rho_i + rho_j) => in
//     (R: bounding radius, rho: inscribed radius); pairs of spheres and pairs
//     of one form Q in closed form; no solve needed for any of these;
//  3. the undecided pairs compacted into a SoA batch for overlap_batch (or
//     contact_function_batch when mu^2 is asked for);
//  4. the pairs found, sorted by i then j whatever the thread count.
//
// Plain types only, like the rest of the public API.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "pwcontact/batch.hpp"

namespace pwcontact {

namespace detail {
// Rebuilds a particle from the numbers a store holds (src/mpi: particles
// sent between ranks keep their radii to the bit). Not part of the API.
struct ParticleRecord;
}  // namespace detail

// Open boundaries, or a periodic box in the convention of HOOMD-blue, GSD
// and freud: edge lengths Lx, Ly, Lz and unitless tilt factors xy, xz, yz,
// whose lattice vectors are the columns of the box matrix
//   h = [[Lx, xy Ly, xz Lz], [0, Ly, yz Lz], [0, 0, Lz]]
// (orthorhombic when the tilts are 0; any origin: the minimum image
// convention only uses differences). A two-dimensional box is periodic in x
// and y (with tilt xy) and open in z, for scenes in the z = 0 plane.
struct Box {
  bool periodic = false;
  std::array<double, 3> length = {0, 0, 0};
  std::array<double, 3> tilt = {0, 0, 0};  // xy, xz, yz
  bool two_dimensional = false;

  static Box open() { return {}; }
  // Throws std::invalid_argument unless every length is positive and finite
  // (and every tilt finite).
  static Box periodic_box(double lx, double ly, double lz);
  static Box triclinic(double lx, double ly, double lz, double xy, double xz, double yz);
  static Box two_dimensional_box(double lx, double ly, double xy = 0);
  // From LAMMPS, whose tilts are lengths (xy, xz, yz of a data file's
  // header): xy / Ly, xz / Lz, yz / Lz here.
  static Box from_lammps(double lx, double ly, double lz, double xy, double xz, double yz);
  // The tilts as LAMMPS writes them: xy Ly, xz Lz, yz Lz.
  std::array<double, 3> lammps_tilts() const;

  bool periodic_along(int axis) const { return periodic && !(two_dimensional && axis == 2); }
  bool orthorhombic() const { return tilt[0] == 0 && tilt[1] == 0 && tilt[2] == 0; }
  // The distance between the faces of the box across each axis (the
  // lengths when orthorhombic): a cutoff's reach must be at most half of it.
  std::array<double, 3> perpendicular_widths() const;
};

// Particles as structure of arrays: centre, quadratic form Q (6 numbers,
// upper triangle row-major, theory eq. 3), and the radii of the spheres
// about the centre that contain it (bounding, the largest semi-axis) and
// that it contains (inscribed, the smallest). The radii are rounded outwards
// and inwards so that the prefilters stay exact: bounding a little larger,
// inscribed a little smaller than the eigenvalues of the stored Q give.
class ParticleStore {
 public:
  std::size_t size() const noexcept { return centre_[0].size(); }
  void reserve(std::size_t n);

  // Q must be finite and positive definite (std::invalid_argument naming the
  // particle otherwise): a scene with an invalid particle has no answer.
  void add(const std::array<double, 3>& centre, const std::array<double, 6>& q);
  // Semi-axes (positive, finite) along the body axes rotated by the unit
  // quaternion (w, x, y, z), converted to Q once (quadratic_form_from_quaternion).
  // Cheaper than add: the radii come from the semi-axes, with no eigensolver.
  void add_axes(const std::array<double, 3>& centre, const std::array<double, 3>& semi_axes,
                const std::array<double, 4>& quaternion);
  // For filling in parallel: resize(n), then set(i, ...) or set_axes(i, ...)
  // for every i (from any thread, each i once), as add and add_axes would
  // (and with the same checks). A slot left unset has no shape: the screens
  // and scenes refuse a store with one (std::invalid_argument naming it).
  void resize(std::size_t n);
  // The first particle that resize() left unset, or size() when there is none.
  std::size_t first_unset() const noexcept;
  // What is wrong with a store that has an unset particle ("particle i was
  // never set (...)"), or "" when every particle is set; require_set throws
  // it as std::invalid_argument, after "<who>: ".
  std::string unset_message() const;
  void require_set(const char* who) const;
  void set(std::size_t i, const std::array<double, 3>& centre, const std::array<double, 6>& q);
  void set_axes(std::size_t i, const std::array<double, 3>& centre,
                const std::array<double, 3>& semi_axes, const std::array<double, 4>& quaternion);
  // An ellipse in the z = 0 plane: centre (x, y), semi-axes a and b (positive,
  // finite), the a axis at angle theta (radians) from x. Stored as the
  // ellipsoid with semi-axes a, b and min(a, b) along z: with Q block
  // diagonal and r12 in the plane, its contact function is exactly the 2D one
  // (Q(lambda)^-1 keeps the blocks apart), whatever the third semi-axis. For
  // a two-dimensional Box.
  void add_ellipse(double x, double y, double a, double b, double theta);
  void set_ellipse(std::size_t i, double x, double y, double a, double b, double theta);

  // Shape types, as HOOMD-blue and GSD give shapes: semi-axes once per type
  // (positive, finite; std::invalid_argument otherwise), then particles by
  // type id and orientation. A typed particle's radii are its type's,
  // computed once; its Q is R diag(a^2) R^T as add_axes makes it (so that
  // particles of one type and one quaternion have the same Q to the bit and
  // their pairs are taken in closed form); a scene whose particles are all of
  // one type is searched as identical shapes (one size class, one reach)
  // by declaration, without comparing radii. Types and untyped particles
  // may be mixed. add_type returns the new type's id (0, 1, ...).
  std::uint32_t add_type(const std::array<double, 3>& semi_axes);
  std::size_t types() const noexcept { return type_axes_.size(); }
  const std::array<double, 3>& type_semi_axes(std::uint32_t type) const;
  // (std::invalid_argument naming the particle for an unknown type, a
  // centre that is not finite or a quaternion that is zero or not finite.)
  void add_typed(const std::array<double, 3>& centre, std::uint32_t type,
                 const std::array<double, 4>& quaternion);
  void set_typed(std::size_t i, const std::array<double, 3>& centre, std::uint32_t type,
                 const std::array<double, 4>& quaternion);
  // Per particle: its type, or `untyped` (added by add, add_axes or add_ellipse).
  static constexpr std::uint32_t untyped = 0xffffffffu;
  const std::vector<std::uint32_t>& type_id() const { return type_id_; }

  // One particle as the store holds it (centre, Q, radii, type), made with
  // the same checks and the same radii as the set functions above, but not
  // stored: a trial position and orientation for a Scene's queries and
  // moves. Only the store makes one (its radii are trusted by the
  // prefilters); `who` names it in the exceptions ("trial particle").
  class Particle {
   public:
    const std::array<double, 3>& centre() const { return centre_; }
    const std::array<double, 6>& q() const { return q_; }
    double bounding_radius() const { return bounding_; }
    double inscribed_radius() const { return inscribed_; }
    double sphere_radius() const { return sphere_; }
    std::uint32_t type() const { return type_; }
    // The same particle translated to another centre (finite; else
    // std::invalid_argument): its form and radii kept, no recomputation.
    Particle moved_to(const std::array<double, 3>& centre) const;

   private:
    friend class ParticleStore;
    friend struct detail::ParticleRecord;
    Particle() = default;
    std::array<double, 3> centre_{};
    std::array<double, 6> q_{};
    double bounding_ = 0, inscribed_ = 0, sphere_ = 0;
    std::uint32_t type_ = untyped;
  };
  static Particle particle(const std::array<double, 3>& centre, const std::array<double, 6>& q,
                           const std::string& who = "trial particle");
  static Particle particle_axes(const std::array<double, 3>& centre,
                                const std::array<double, 3>& semi_axes,
                                const std::array<double, 4>& quaternion,
                                const std::string& who = "trial particle");
  Particle particle_typed(const std::array<double, 3>& centre, std::uint32_t type,
                          const std::array<double, 4>& quaternion,
                          const std::string& who = "trial particle") const;
  // Particle i as stored (i < size(); std::out_of_range otherwise).
  Particle particle_at(std::size_t i) const;
  // Stores a particle made above at index i (< size()), or at the end.
  // (A typed particle's type must exist in this store, with its shape: see
  // check_type.)
  void set_particle(std::size_t i, const Particle& p);
  // std::invalid_argument (its message begins with `who`) unless p is
  // untyped or of a type of this store with that type's shape (its radii,
  // and the trace of Q within 1e-12: a particle another store made with
  // another shape under the same type id was taken as this store's type).
  void check_type(const Particle& p, const char* who) const;
  bool type_fits(const Particle& p) const noexcept;  // (check_type without the exception)
  void add_particle(const Particle& p);
  // Removes particle i by moving the last particle into its place
  // (std::out_of_range for i >= size()).
  void swap_remove(std::size_t i);

  const std::vector<double>& centre(int k) const { return centre_[k]; }
  const std::vector<double>& q(int k) const { return q_[k]; }
  const std::vector<double>& bounding_radius() const { return bounding_; }
  const std::vector<double>& inscribed_radius() const { return inscribed_; }
  // The radius of a particle that is a sphere (Q = a^2 I exactly), else 0:
  // pairs of spheres are decided in closed form, mu = |r| / (a_i + a_j).
  const std::vector<double>& sphere_radius() const { return sphere_; }

 private:
  // A particle with the smallest and largest eigenvalues of its Q (each
  // within a few eps |Q|), rounding the radii to the safe side.
  static Particle untyped_particle(const std::string& who, const std::array<double, 3>& centre,
                                   const std::array<double, 6>& q, double smallest, double largest);
  struct Radii {
    double bounding, inscribed, sphere;
  };
  static Radii radii_of(const std::string& who, const std::array<double, 6>& q, double smallest,
                        double largest);
  template <class Visit>
  void for_each_array(Visit&& visit);  // every per-particle array of doubles
  std::vector<double> centre_[3], q_[6], bounding_, inscribed_, sphere_;
  std::vector<std::uint32_t> type_id_;
  // Per type: semi-axes, and the radii untyped_particle() would give its particles.
  std::vector<std::array<double, 3>> type_axes_;
  std::vector<Radii> type_radii_;
};

struct ScreenOptions {
  double cutoff = 1;      // mu_cut: a pair is found when mu < cutoff; positive and finite
  bool with_mu2 = false;  // also report mu^2 of every pair found (then every pair not found
                          // apart is solved: the inscribed prefilter gives no mu^2)
  int threads = 0;        // OpenMP threads for every stage, 0 .. 1024; 0: omp_get_max_threads()
  BatchOptions batch;     // precision, isa, ... of the solve (its threads are ignored)
  // Called now and then from one thread with the fraction of the candidate
  // search done (0 .. 1), e.g. for a progress bar; may be empty.
  std::function<void(double fraction)> progress;
};

// The pairs found: i[k] < j[k], sorted by i then j; mu2[k] with with_mu2.
struct ScreenedPairs {
  std::vector<std::uint32_t> i, j;
  std::vector<double> mu2;
  std::size_t size() const noexcept { return i.size(); }
};

// What users need per particle, from the pairs found (any ScreenedPairs:
// sorted, i < j, each once):
// - the number of pairs each particle is in (its overlaps with cutoff 1);
std::vector<std::uint32_t> pair_counts(const ScreenedPairs& pairs, std::size_t particles);
// - the pairs as a neighbour list in CSR form: particle k's neighbours are
//   neighbors[offsets[k]] .. neighbors[offsets[k + 1] - 1], in increasing
//   order, with mu2 alongside when the pairs have it; both directions (j
//   among i's neighbours and i among j's) unless both_directions is false
//   (then only j > k among k's).
struct NeighborList {
  std::vector<std::size_t> offsets;  // particles + 1
  std::vector<std::uint32_t> neighbors;
  std::vector<double> mu2;
};
NeighborList neighbor_list(const ScreenedPairs& pairs, std::size_t particles,
                           bool both_directions = true);

// What a screen did, stage by stage.
struct ScreenReport {
  std::size_t particles = 0;
  int threads = 0;                  // the thread count used
  std::size_t size_classes = 0;     // cell lists built (one per class of bounding radius)
  bool identical_shapes = false;    // every particle the same bounding and inscribed radius
                                    // (to 1e-12), or all of one shape type: one reach for
                                    // every pair in the search
  bool one_type = false;            // every particle of one shape type (ParticleStore types)
  std::size_t candidate_pairs = 0;  // pairs whose bounding reaches the cell lists compared
  std::size_t decided_out = 0;      // |r| >= cutoff (R_i + R_j): apart, no solve
  std::size_t decided_out_by_projection = 0;  // left by that, apart by a separating plane
                                              // normal to r12, no solve
  std::size_t decided_in = 0;                 // |r| < cutoff (rho_i + rho_j): found, no solve
  std::size_t decided_spheres = 0;    // pairs of spheres left by those: closed form, no solve
  std::size_t decided_same_form = 0;  // pairs of one form Q (same shape and orientation) left:
                                      // mu^2 = r^T Q^-1 r / 4, no solve (cond(Q) <= 1e4)
  std::size_t solved = 0;             // pairs given to the batch path
  std::size_t invalid = 0;            // solved pairs with an invalid status (not found)
  std::size_t found = 0;
  BatchReport batch;  // of the solve
  // Seconds per stage: size classes and cell lists; candidates and
  // prefilters; compaction into a batch; the solve; collecting and sorting.
  double seconds_cells = 0, seconds_candidates = 0, seconds_compaction = 0, seconds_solve = 0,
         seconds_output = 0;
  double seconds_total() const {
    return seconds_cells + seconds_candidates + seconds_compaction + seconds_solve + seconds_output;
  }
};

// Every pair of the store with mu < options.cutoff. Throws
// std::invalid_argument for a bad cutoff, 2^31 particles or more, or a
// periodic box shorter than twice the largest reach cutoff * 2 max R in some
// direction (the minimum image would then miss pairs).
ScreenReport screen_pairs(const ParticleStore& particles, const Box& box,
                          const ScreenOptions& options, ScreenedPairs& out);

// Memory one screen leaves for the next: the cell lists' copies of the
// particles (about 100 bytes each), the threads' buffers of pairs, the sort's
// arrays, and out's storage. A simulation that screens its scene every so
// many steps passes the same workspace (and the same out) to each call: the
// calls after the first reuse that memory instead of asking the system for
// fresh pages, which the kernel maps and clears on their first touch (on
// the 1M demo scene measured 2-7 % of a screen with 1 thread, more at 4M
// and varying with the host: see README). The answers are the same with or
// without one. The workspace
// holds the memory of the largest screen it served until release() or its
// destruction; bytes() tells how much, as of the end of the last screen (or
// release): asked while a screen runs, from another thread or a progress
// callback, it gives that figure, not the memory the running screen is
// growing. One screen at a time: a second call while one runs throws
// std::logic_error, and so does release() while one runs (from another
// thread, or a progress callback).
class ScreenWorkspace {
 public:
  ScreenWorkspace();
  ~ScreenWorkspace();
  ScreenWorkspace(ScreenWorkspace&&) noexcept;
  ScreenWorkspace& operator=(ScreenWorkspace&&) noexcept;
  std::size_t bytes() const noexcept;
  void release();
  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  friend ScreenReport screen_pairs(const ParticleStore&, const Box&, const ScreenOptions&,
                                   ScreenedPairs&, ScreenWorkspace&);
};

// screen_pairs in a workspace's memory (out's storage reused too). Throws
// as screen_pairs, and std::logic_error as above.
ScreenReport screen_pairs(const ParticleStore& particles, const Box& box,
                          const ScreenOptions& options, ScreenedPairs& out,
                          ScreenWorkspace& workspace);

// The same pipeline (prefilters, solve, sorted output) on a candidate list of
// one's own, e.g. from an existing neighbour list: the pairs (first[k],
// second[k]), k < count, in either order; a pair listed more than once is
// reported once. r12 by the minimum image in a periodic box (which must then
// be at least twice the largest reach, as for screen_pairs). Throws
// std::invalid_argument for an index out of range or a particle paired with
// itself (naming the candidate), and as screen_pairs. The report has no cell
// lists (size_classes 0, seconds_cells 0).
ScreenReport screen_candidates(const ParticleStore& particles, const Box& box,
                               const std::uint32_t* first, const std::uint32_t* second,
                               std::size_t count, const ScreenOptions& options, ScreenedPairs& out);

// Every pair (i < j) the cell lists compare for this cutoff — a superset of
// the pairs with mu < cutoff, before any prefilter — with r12 = c_j - c_i by
// the minimum image: visit(thread, i, j, r12) is called from the OpenMP
// thread (0 .. threads - 1) that found the pair, in no particular order. For
// pipelines of one's own, and to measure against. Throws as screen_pairs.
void for_each_candidate_pair(const ParticleStore& particles, const Box& box, double cutoff,
                             int threads,
                             const std::function<void(int thread, std::uint32_t i, std::uint32_t j,
                                                      const double r12[3])>& visit);

}  // namespace pwcontact
