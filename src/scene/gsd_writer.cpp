// GsdWriter: GSD's file layer 2.0 written from its specification. Chunks go
// one after the other behind the header; finish() appends the index (sorted
// by frame, then name id, as version 2 requires) and the name list, then
// rewrites the header with their places.
#include <algorithm>
#include <cstring>
#include <ostream>
#include <stdexcept>

#include "pwcontact/scene_files.hpp"
#include "scene/gsd_format.hpp"

namespace pwcontact {

using namespace detail::gsd;

namespace {

Header header_of(std::uint64_t index_location, std::uint64_t index_entries,
                 std::uint64_t namelist_location, std::uint64_t namelist_segments) {
  Header h{};
  h.magic = gsd_magic;
  h.index_location = index_location;
  h.index_allocated_entries = index_entries;
  h.namelist_location = namelist_location;
  h.namelist_allocated_entries = namelist_segments;
  h.schema_version = (1u << 16) | 4u;  // hoomd schema 1.4
  h.gsd_version = 2u << 16;            // file layer 2.0
  std::strncpy(h.application, "pwcontact", sizeof h.application - 1);
  std::strncpy(h.schema, "hoomd", sizeof h.schema - 1);
  return h;
}

}  // namespace

GsdWriter::GsdWriter(std::ostream& out) : out_(out) {
  // A header that says "no index" until finish() rewrites it.
  const Header h = header_of(0, 0, 0, 0);
  out_.write(reinterpret_cast<const char*>(&h), sizeof h);
  if (!out_) throw std::runtime_error("GsdWriter: cannot write the header");
  end_ = sizeof h;
}

void GsdWriter::write_raw(const std::string& name, std::uint8_t type, std::uint64_t rows,
                          std::uint64_t count, const void* data) {
  if (finished_) throw std::invalid_argument("GsdWriter: " + name + " written after finish()");
  // (File layer 2.0 keeps the names one after the other, each ended by a
  // zero byte: any length; HOOMD-blue's logged quantities take 64 and more.)
  if (name.empty() || name.find('\0') != std::string::npos)
    throw std::invalid_argument("GsdWriter: a chunk name must be non-empty text, not '" + name +
                                "'");
  if (rows == 0 || count % rows != 0 || count / rows > 0xffffffffu)
    throw std::invalid_argument("GsdWriter: " + name + ": " + std::to_string(count) +
                                " values are not " + std::to_string(rows) + " rows");
  auto [id, added] = ids_.emplace(name, std::uint16_t(names_.size()));
  if (added) {
    if (names_.size() == 0xffff) throw std::invalid_argument("GsdWriter: too many chunk names");
    names_.push_back(name);
  }
  for (const Entry& e : index_)
    if (e.frame == frame_ && e.id == id->second)
      throw std::invalid_argument("GsdWriter: " + name + " written twice in frame " +
                                  std::to_string(frame_));
  const std::uint64_t bytes = count * size_of(type);
  out_.write(static_cast<const char*>(data), std::streamsize(bytes));
  if (!out_) throw std::runtime_error("GsdWriter: cannot write chunk " + name);
  index_.push_back({frame_, rows, end_, std::uint32_t(count / rows), id->second, type});
  end_ += std::int64_t(bytes);
}

void GsdWriter::write(const std::string& name, const std::vector<float>& values,
                      std::uint64_t rows) {
  write_raw(name, float32, rows, values.size(), values.data());
}
void GsdWriter::write(const std::string& name, const std::vector<double>& values,
                      std::uint64_t rows) {
  write_raw(name, float64, rows, values.size(), values.data());
}
void GsdWriter::write(const std::string& name, const std::vector<std::uint32_t>& values,
                      std::uint64_t rows) {
  write_raw(name, uint32, rows, values.size(), values.data());
}
void GsdWriter::write(const std::string& name, const std::vector<std::uint64_t>& values,
                      std::uint64_t rows) {
  write_raw(name, uint64, rows, values.size(), values.data());
}

void GsdWriter::write(const std::string& name, const std::vector<std::string>& rows) {
  std::size_t width = 1;
  for (const std::string& row : rows) width = std::max(width, row.size() + 1);
  std::vector<char> table(rows.size() * width, 0);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    if (std::memchr(rows[r].data(), 0, rows[r].size()))
      throw std::invalid_argument("GsdWriter: " + name + ": row " + std::to_string(r) +
                                  " holds a zero byte");
    std::memcpy(&table[r * width], rows[r].data(), rows[r].size());
  }
  write_raw(name, int8, rows.size(), table.size(), table.data());
}

void GsdWriter::write_chunk(const std::string& name, std::uint8_t type, std::uint64_t rows,
                            std::uint32_t columns, const void* data) {
  if (size_of(type) == 0)
    throw std::invalid_argument("GsdWriter: " + name + ": " + std::to_string(type) +
                                " is not a GSD type code");
  if (columns == 0 || rows > std::uint64_t(-1) / columns)
    throw std::invalid_argument("GsdWriter: " + name + ": " + std::to_string(rows) + " x " +
                                std::to_string(columns) + " elements");
  write_raw(name, type, rows, rows * columns, data);
}

void GsdWriter::end_frame() { ++frame_; }

void GsdWriter::finish() {
  if (finished_) return;
  finished_ = true;
  std::stable_sort(index_.begin(), index_.end(), [](const Entry& a, const Entry& b) {
    return a.frame != b.frame ? a.frame < b.frame : a.id < b.id;
  });
  const std::int64_t index_location = end_;
  for (const Entry& e : index_) {
    const IndexEntry stored{e.frame, e.rows, e.location, e.columns, e.id, e.type, 0};
    out_.write(reinterpret_cast<const char*>(&stored), sizeof stored);
  }
  std::string names;
  for (const std::string& n : names_) names.append(n).push_back('\0');
  names.push_back('\0');  // the empty name that ends the list
  const std::size_t segments = (names.size() + name_segment - 1) / name_segment;
  names.resize(segments * name_segment, '\0');
  const std::int64_t namelist_location =
      index_location + std::int64_t(index_.size() * sizeof(IndexEntry));
  out_.write(names.data(), std::streamsize(names.size()));
  const Header h = header_of(std::uint64_t(index_location), index_.size(),
                             std::uint64_t(namelist_location), segments);
  out_.seekp(0);
  out_.write(reinterpret_cast<const char*>(&h), sizeof h);
  out_.flush();
  if (!out_) throw std::runtime_error("GsdWriter: cannot write the index, the names or the header");
}

}  // namespace pwcontact
