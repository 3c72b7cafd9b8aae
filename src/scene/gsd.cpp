// A read-only GSD reader, written from the format's published specification
// (the "file layer" of GSD 1.x and 2.x, and the "hoomd" schema): a 256-byte
// header, an index of 32-byte entries (frame, N, location, M, name id,
// type), a list of chunk names, and raw little-endian chunks.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "number_text.hpp"
#include "parallel_errors.hpp"
#include "pwcontact/scene_files.hpp"
#include "scene/gsd_format.hpp"
#include "scene/shape_json.hpp"

namespace pwcontact {
namespace {

using namespace detail::gsd;

class GsdFile {
 public:
  explicit GsdFile(const std::string& path) : path_(path) {
    // (O_NONBLOCK: opening a named pipe without it waits for a writer,
    // before the check below can refuse it; it changes nothing for a file.)
    descriptor_ = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (descriptor_ < 0)
      throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
    struct stat info {};
    if (fstat(descriptor_, &info) != 0) fail_io();
    // (A pipe has no size and cannot be read at offsets: refused by name,
    // where it was taken for a file of 0 bytes.)
    if (!S_ISREG(info.st_mode))
      malformed(
          "not a regular file (a pipe or a device?): a GSD file is read at the offsets its "
          "index gives, so from a file");
    size_ = std::uint64_t(info.st_size);
    Header header;
    if (size_ < sizeof header)
      malformed("shorter than a GSD header (" + std::to_string(size_) + " bytes)");
    read_at(0, &header, sizeof header);
    if (header.magic != gsd_magic) malformed("not a GSD file (no GSD magic number)");
    version_ = header.gsd_version;
    const std::uint32_t major = version_ >> 16;
    if (!(major == 1 || major == 2 || version_ == 3))  // 0.3, 1.x, 2.x
      malformed("GSD file layer version " + std::to_string(major) + "." +
                std::to_string(version_ & 0xffff) + " is not one this reader knows (1.x, 2.x)");
    read_names(header);
    read_index(header);
  }
  ~GsdFile() { close(descriptor_); }
  GsdFile(const GsdFile&) = delete;
  GsdFile& operator=(const GsdFile&) = delete;

  std::uint64_t frames() const { return index_.empty() ? 0 : index_.back().frame + 1; }
  const std::string& path() const { return path_; }

  // The entry of `name` in `frame`, null if the frame has none.
  const IndexEntry* find(std::uint64_t frame, const std::string& name) const {
    const auto id = ids_.find(name);
    if (id == ids_.end()) return nullptr;
    // Version 2 indices are sorted by frame, then id; older ones by frame.
    auto first = std::lower_bound(index_.begin(), index_.end(), frame,
                                  [](const IndexEntry& e, std::uint64_t f) { return e.frame < f; });
    for (; first != index_.end() && first->frame == frame; ++first)
      if (first->id == id->second) return &*first;
    return nullptr;
  }

  // The chunk's values converted to T (numbers only), checked against the
  // shape the schema gives it. Into an integer T, a value must be a whole
  // number T holds (the schema stores N, dimensions and typeid as unsigned
  // integers; another type is taken where its values are such numbers):
  // a typeid of 2^32 + 1 was read as 1, of 0.9 as 0, a dimensions of 2.9
  // as 2, each without a word.
  template <class T>
  std::vector<T> numbers(const IndexEntry& e, const std::string& name, std::uint64_t rows,
                         std::uint32_t columns) const {
    check_shape(e, name, rows, columns);
    const std::size_t count = std::size_t(rows) * columns;
    std::vector<unsigned char> raw = bytes(e, name);
    std::vector<T> out(count);
    auto convert = [&](auto tag) {
      using S = decltype(tag);
      for (std::size_t k = 0; k < count; ++k) {
        S v;
        std::memcpy(&v, raw.data() + k * sizeof(S), sizeof(S));
        if constexpr (std::is_integral<T>::value) {
          static_assert(std::is_unsigned<T>::value, "the schema's integers are unsigned");
          bool whole = true;
          if constexpr (std::is_floating_point<S>::value)
            whole = v >= 0 && v < std::ldexp(1.0, std::numeric_limits<T>::digits) &&
                    double(v) == std::floor(double(v));
          else if constexpr (std::is_signed<S>::value)
            whole = v >= 0 && std::uint64_t(v) <= std::uint64_t(std::numeric_limits<T>::max());
          else
            whole = std::uint64_t(v) <= std::uint64_t(std::numeric_limits<T>::max());
          if (!whole)
            malformed("chunk " + name + " of frame " + std::to_string(e.frame) + ", row " +
                      std::to_string(k / columns) + ": " + detail::number_text(double(v)) +
                      " is not a whole number from 0 to " +
                      std::to_string(std::numeric_limits<T>::max()));
        }
        out[k] = T(v);
      }
    };
    switch (e.type) {
      case uint8: convert(std::uint8_t()); break;
      case uint16: convert(std::uint16_t()); break;
      case uint32: convert(std::uint32_t()); break;
      case uint64: convert(std::uint64_t()); break;
      case int8: convert(std::int8_t()); break;
      case int16: convert(std::int16_t()); break;
      case int32: convert(std::int32_t()); break;
      case int64: convert(std::int64_t()); break;
      case float32: convert(float()); break;
      case float64: convert(double()); break;
      default:
        malformed("chunk " + name + " does not hold numbers (type " + std::to_string(e.type) + ")");
    }
    return out;
  }

  // The chunk is `rows` x `columns`, as the schema says.
  void check_shape(const IndexEntry& e, const std::string& name, std::uint64_t rows,
                   std::uint32_t columns) const {
    if (e.n != rows || e.m != columns)
      malformed("chunk " + name + " of frame " + std::to_string(e.frame) + " is " +
                std::to_string(e.n) + "x" + std::to_string(e.m) + ", expected " +
                std::to_string(rows) + "x" + std::to_string(columns));
  }

  // The rows of a chunk of characters, each a zero-terminated string.
  std::vector<std::string> strings(const IndexEntry& e, const std::string& name) const {
    if (e.type != int8 && e.type != uint8 && e.type != character)
      malformed("chunk " + name + " does not hold characters (type " + std::to_string(e.type) +
                ")");
    // (Rows of no characters take no bytes: the file's size would not bound
    // how many strings are made.)
    if (e.m == 0 && e.n != 0)
      malformed("chunk " + name + " of frame " + std::to_string(e.frame) + " has " +
                std::to_string(e.n) + " rows of no characters");
    const std::vector<unsigned char> raw = bytes(e, name);
    std::vector<std::string> rows;
    for (std::uint64_t r = 0; r < e.n; ++r) {
      const char* row = reinterpret_cast<const char*>(raw.data() + r * e.m);
      rows.emplace_back(row, strnlen(row, e.m));
    }
    return rows;
  }

  // The entries of `frame`, in the index's order.
  std::vector<const IndexEntry*> entries(std::uint64_t frame) const {
    std::vector<const IndexEntry*> found;
    auto first = std::lower_bound(index_.begin(), index_.end(), frame,
                                  [](const IndexEntry& e, std::uint64_t f) { return e.frame < f; });
    for (; first != index_.end() && first->frame == frame; ++first) found.push_back(&*first);
    return found;
  }
  // The name of an entry's id ("" if the list lacks it).
  std::string name_of(std::uint16_t id) const {
    for (const auto& [name, i] : ids_)
      if (i == id) return name;
    return {};
  }

  // The chunk's bytes as stored.
  std::vector<unsigned char> bytes(const IndexEntry& e, const std::string& name) const {
    const std::uint64_t element = size_of(e.type);
    if (element == 0) malformed("chunk " + name + " has an unknown type " + std::to_string(e.type));
    // (Overflow-safe: a chunk larger than the file is refused.)
    if (e.m != 0 && e.n > size_ / e.m / element)
      malformed("truncated or corrupt: chunk " + name + " of frame " + std::to_string(e.frame) +
                " (" + std::to_string(e.n) + "x" + std::to_string(e.m) +
                ") is larger than the file");
    const std::uint64_t count = e.n * e.m * element;
    if (e.location < 0 || std::uint64_t(e.location) > size_ ||
        count > size_ - std::uint64_t(e.location))
      malformed("truncated: chunk " + name + " of frame " + std::to_string(e.frame) +
                " ends beyond the file (" + std::to_string(size_) + " bytes)");
    std::vector<unsigned char> raw(count);
    if (count) read_at(std::uint64_t(e.location), raw.data(), count);
    return raw;
  }

  [[noreturn]] void malformed(const std::string& what) const {
    throw std::invalid_argument(path_ + ": " + what);
  }

 private:
  [[noreturn]] void fail_io() const {
    throw std::runtime_error("cannot read " + path_ + ": " + std::strerror(errno));
  }

  void read_at(std::uint64_t offset, void* to, std::size_t count) const {
    auto* p = static_cast<char*>(to);
    while (count > 0) {
      const ssize_t got = pread(descriptor_, p, count, off_t(offset));
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) fail_io();
      if (got == 0)
        malformed("truncated: a block at byte " + std::to_string(offset) + " ends beyond the file");
      p += got;
      offset += std::uint64_t(got);
      count -= std::size_t(got);
    }
  }

  void read_names(const Header& h) {
    if (h.namelist_allocated_entries > size_ / name_segment ||
        h.namelist_location > size_ - h.namelist_allocated_entries * name_segment)
      malformed("truncated or corrupt: the list of chunk names lies beyond the file");
    std::vector<char> names(h.namelist_allocated_entries * name_segment);
    if (!names.empty()) read_at(h.namelist_location, names.data(), names.size());
    const bool fixed = (version_ >> 16) < 2;  // version 1: 64 bytes per name
    std::size_t at = 0;
    for (std::uint16_t id = 0; at < names.size() && names[at] != 0; ++id) {
      const std::size_t length = strnlen(&names[at], names.size() - at);
      ids_.emplace(std::string(&names[at], length), id);
      at += fixed ? name_segment : length + 1;
    }
  }

  void read_index(const Header& h) {
    if (h.index_allocated_entries > size_ / sizeof(IndexEntry) ||
        h.index_location > size_ - h.index_allocated_entries * sizeof(IndexEntry))
      malformed("truncated or corrupt: the index lies beyond the file");
    index_.resize(h.index_allocated_entries);
    if (!index_.empty())
      read_at(h.index_location, index_.data(), index_.size() * sizeof(IndexEntry));
    // The first entry at location 0 ends the list.
    std::size_t used = 0;
    while (used < index_.size() && index_[used].location != 0) ++used;
    index_.resize(used);
    for (std::size_t k = 1; k < index_.size(); ++k)
      if (index_[k].frame < index_[k - 1].frame) malformed("corrupt index: frames out of order");
  }

  std::string path_;
  int descriptor_ = -1;
  std::uint64_t size_ = 0;
  std::uint32_t version_ = 0;
  std::unordered_map<std::string, std::uint16_t> ids_;
  std::vector<IndexEntry> index_;
};

// A chunk of the frame as the hoomd schema defines it: the frame's own, or
// frame 0's when it has as many rows, or none (the default applies).
const IndexEntry* chunk(const GsdFile& file, std::uint64_t frame, const std::string& name,
                        std::uint64_t rows) {
  if (const IndexEntry* e = file.find(frame, name)) return e;
  const IndexEntry* first = file.find(0, name);
  return first && first->n == rows ? first : nullptr;
}

}  // namespace

Scene read_gsd(const std::string& path, std::int64_t frame) {
  const GsdFile file(path);
  Scene scene;
  scene.frames = file.frames();
  if (scene.frames == 0) file.malformed("the file has no frames");
  const std::int64_t count = std::int64_t(scene.frames);
  if (frame < -count || frame >= count)
    file.malformed("frame " + std::to_string(frame) + " is not in the file (it has " +
                   std::to_string(scene.frames) + " frames)");
  const std::uint64_t f = std::uint64_t(frame < 0 ? count + frame : frame);
  scene.frame = f;
  const std::string where = "frame " + std::to_string(f);

  std::uint64_t n = 0;
  if (const IndexEntry* e =
          file.find(f, "particles/N") ? file.find(f, "particles/N") : file.find(0, "particles/N"))
    n = file.numbers<std::uint64_t>(*e, "particles/N", 1, 1)[0];
  if (n >= (std::uint64_t(1) << 31))
    file.malformed(where + ": " + std::to_string(n) + " particles, more than 2^31 - 1");

  std::vector<double> box = {1, 1, 1, 0, 0, 0};
  if (const IndexEntry* e = chunk(file, f, "configuration/box", 6))
    box = file.numbers<double>(*e, "configuration/box", 6, 1);
  unsigned dimensions = 3;
  if (const IndexEntry* e = chunk(file, f, "configuration/dimensions", 1))
    dimensions = file.numbers<unsigned>(*e, "configuration/dimensions", 1, 1)[0];
  if (dimensions != 2 && dimensions != 3)
    file.malformed(where + ": configuration/dimensions is " + std::to_string(dimensions) +
                   ", not 2 or 3");
  try {
    scene.box = dimensions == 2 ? Box::two_dimensional_box(box[0], box[1], box[3])
                                : Box::triclinic(box[0], box[1], box[2], box[3], box[4], box[5]);
  } catch (const std::invalid_argument& e) {
    file.malformed(where + ": configuration/box: " + e.what());
  }

  // The per-particle chunks are checked against N before anything of N
  // particles is allocated: a chunk that fits the file bounds N, and a
  // declared N that no chunk matches is refused naming the chunk.
  const IndexEntry* position_entry = chunk(file, f, "particles/position", n);
  const IndexEntry* orientation_entry = chunk(file, f, "particles/orientation", n);
  const IndexEntry* type_id_entry = chunk(file, f, "particles/typeid", n);
  if (position_entry) file.check_shape(*position_entry, "particles/position", n, 3);
  if (orientation_entry) file.check_shape(*orientation_entry, "particles/orientation", n, 4);
  if (type_id_entry) file.check_shape(*type_id_entry, "particles/typeid", n, 1);
  // (The schema's default puts every particle at the origin: of a frame of
  // many particles, a file that gives no positions, and an N that nothing
  // bounds, which N x 3 zeros of up to 2^31 particles would exhaust memory
  // for.)
  if (!position_entry && n > 1)
    file.malformed(where + ": " + std::to_string(n) +
                   " particles but no particles/position (in this frame or frame 0): every "
                   "particle would sit at the origin");
  const IndexEntry* types_entry = file.find(f, "particles/types") ? file.find(f, "particles/types")
                                                                  : file.find(0, "particles/types");
  const std::size_t types = types_entry ? std::size_t(types_entry->n) : 1;
  // One shape per type: the frame's own chunk as well as frame 0's (which
  // chunk() takes only with as many rows), or a type's shape would be read
  // beyond the chunk. (Checked before the names are made: a file of many
  // one-byte names and no shapes made a string of each, 36 times its size.)
  const IndexEntry* shapes_entry = chunk(file, f, "particles/type_shapes", types);
  if (!shapes_entry)
    file.malformed(where + ": no particles/type_shapes for its " + std::to_string(types) +
                   " types: the file does not give the particles' shapes");
  if (shapes_entry->n != types)
    file.malformed(where + ": particles/type_shapes has " + std::to_string(shapes_entry->n) +
                   " rows for " + std::to_string(types) + " types");
  scene.type_names = {"A"};
  if (types_entry) scene.type_names = file.strings(*types_entry, "particles/types");
  const std::vector<std::string> shapes_json = file.strings(*shapes_entry, "particles/type_shapes");

  // (A chunk's values are read, its size checked against the file's, before
  // they are allocated; the defaults only when the chunk is absent.)
  const std::vector<double> position =
      position_entry ? file.numbers<double>(*position_entry, "particles/position", n, 3)
                     : std::vector<double>(3 * n, 0.0);
  const std::vector<double> orientation =
      orientation_entry ? file.numbers<double>(*orientation_entry, "particles/orientation", n, 4)
                        : std::vector<double>();
  std::vector<std::uint32_t> type_id =
      type_id_entry ? file.numbers<std::uint32_t>(*type_id_entry, "particles/typeid", n, 1)
                    : std::vector<std::uint32_t>(n, 0);
  std::vector<detail::ShapeAxes> shapes;
  for (std::size_t t = 0; t < types; ++t) {
    try {
      shapes.push_back(detail::parse_shape(shapes_json[t], dimensions == 2));
    } catch (const std::invalid_argument& e) {
      file.malformed(where + ": type " + std::to_string(t) + " ('" +
                     detail::printable(scene.type_names[t]) + "'): " + e.what());
    }
  }

  // Three dimensions: the store's shape types, one per GSD type (radii once
  // per type; one type declares identical shapes).
  if (dimensions == 3)
    for (std::size_t t = 0; t < types; ++t) {
      try {
        scene.particles.add_type(shapes[t].a);
      } catch (const std::invalid_argument& e) {
        file.malformed(where + ": particles/type_shapes, type " + std::to_string(t) + " ('" +
                       detail::printable(scene.type_names[t]) + "'): " + e.what());
      }
    }
  scene.particles.resize(n);
  detail::ParallelErrors errors;
  const std::int64_t signed_n = std::int64_t(n);
#pragma omp parallel for schedule(static)
  for (std::int64_t signed_i = 0; signed_i < signed_n; ++signed_i)
    errors.run([&] {
      const std::size_t i = std::size_t(signed_i);
      if (type_id[i] >= types)
        file.malformed(where + ": particle " + std::to_string(i) + " has typeid " +
                       std::to_string(type_id[i]) + ", but there are " + std::to_string(types) +
                       " types");
      const detail::ShapeAxes& shape = shapes[type_id[i]];
      const std::array<double, 4> q =
          orientation.empty()
              ? std::array<double, 4>{1, 0, 0, 0}
              : std::array<double, 4>{orientation[4 * i], orientation[4 * i + 1],
                                      orientation[4 * i + 2], orientation[4 * i + 3]};
      try {
        if (dimensions == 2) {
          // The angle of the body's x axis in the plane, from the rotation,
          // which must be about z (x, y = 0 up to the file's float32
          // rounding), as must the centre lie in the plane.
          const double w = q[0], x = q[1], y = q[2], z = q[3], norm = w * w + x * x + y * y + z * z;
          if (!(norm > 0) || !std::isfinite(norm))
            throw std::invalid_argument("its orientation is zero or not finite");
          if (x * x + y * y > 1e-12 * norm)
            throw std::invalid_argument("a two-dimensional scene, but its orientation (" +
                                        detail::number_text(w) + ", " + detail::number_text(x) +
                                        ", " + detail::number_text(y) + ", " +
                                        detail::number_text(z) + ") is not a rotation about z");
          if (position[3 * i + 2] != 0)
            throw std::invalid_argument("a two-dimensional scene, but its z is " +
                                        detail::number_text(position[3 * i + 2]) + ", not 0");
          const double theta = std::atan2(2 * (x * y + w * z), w * w + x * x - y * y - z * z);
          scene.particles.set_ellipse(i, position[3 * i], position[3 * i + 1], shape.a[0],
                                      shape.a[1], theta);
        } else {
          scene.particles.set_typed(i, {position[3 * i], position[3 * i + 1], position[3 * i + 2]},
                                    type_id[i], q);
        }
      } catch (const std::invalid_argument& e) {
        file.malformed(where + ": particle " + std::to_string(i) + ": " +
                       detail::store_message(e, i));
      }
    });
  errors.rethrow_if_failed();
  scene.type_id = std::move(type_id);
  return scene;
}

void write_gsd_frame_with_values(const std::string& input, std::int64_t frame,
                                 const std::string& name, const std::vector<std::uint32_t>& values,
                                 std::ostream& out) {
  // The frame as read_gsd reads it: its particle count, and the checks.
  const Scene scene = read_gsd(input, frame);
  const std::size_t n = scene.particles.size();
  if (values.size() != n)
    throw std::invalid_argument("write_gsd_frame_with_values: " + std::to_string(values.size()) +
                                " values for the " + std::to_string(n) + " particles of " + input);
  const GsdFile file(input);
  const std::string log_name = "log/particles/" + name;
  GsdWriter writer(out);
  // The frame's own chunks, then those it takes from frame 0 (per-particle
  // ones only when frame 0 has as many particles, as the schema says).
  std::vector<std::string> written;
  auto copy = [&](const IndexEntry& e, const std::string& chunk_name) {
    if (chunk_name == log_name || chunk_name.empty()) return;
    if (std::find(written.begin(), written.end(), chunk_name) != written.end()) return;
    if (e.n == 0 || e.m == 0) return;  // (an empty chunk: nothing to copy)
    const std::vector<unsigned char> raw = file.bytes(e, chunk_name);
    writer.write_chunk(chunk_name, e.type, e.n, e.m, raw.data());
    written.push_back(chunk_name);
  };
  for (const IndexEntry* e : file.entries(scene.frame)) copy(*e, file.name_of(e->id));
  if (scene.frame != 0)
    for (const IndexEntry* e : file.entries(0)) {
      const std::string chunk_name = file.name_of(e->id);
      const bool per_particle = chunk_name.rfind("particles/", 0) == 0 &&
                                chunk_name != "particles/N" && chunk_name != "particles/types" &&
                                chunk_name != "particles/type_shapes";
      if (!per_particle || e->n == n) copy(*e, chunk_name);
    }
  if (n > 0) writer.write(log_name, values, n);
  writer.end_frame();
  writer.finish();
}

}  // namespace pwcontact
