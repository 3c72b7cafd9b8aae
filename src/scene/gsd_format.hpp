// GSD's file layer as stored (little-endian, packed), shared by the reader
// and the writer: a 256-byte header, 32-byte index entries, the list of
// chunk names, and the chunks' element types.
#pragma once

#include <cstddef>
#include <cstdint>

namespace pwcontact::detail::gsd {

struct Header {
  std::uint64_t magic;
  std::uint64_t index_location;
  std::uint64_t index_allocated_entries;
  std::uint64_t namelist_location;
  std::uint64_t namelist_allocated_entries;  // in 64-byte segments
  std::uint32_t schema_version;              // major << 16 | minor
  std::uint32_t gsd_version;                 // major << 16 | minor
  char application[64];
  char schema[64];
  char reserved[80];
};
static_assert(sizeof(Header) == 256, "the GSD header is 256 bytes");

// One chunk: n rows of m elements of `type` at byte `location`, of name
// `id` (its place in the name list). Version 2 sorts them by frame, then
// id; an entry at location 0 ends the list.
struct IndexEntry {
  std::uint64_t frame;
  std::uint64_t n;
  std::int64_t location;
  std::uint32_t m;
  std::uint16_t id;
  std::uint8_t type;
  std::uint8_t flags;
};
static_assert(sizeof(IndexEntry) == 32, "a GSD index entry is 32 bytes");

constexpr std::uint64_t gsd_magic = 0x65DF65DF65DF65DFull;
// Version 2's name list: names one after the other, each ended by a zero
// byte, the list by an empty name; allocated in segments of 64 bytes
// (version 1: one name per 64-byte segment).
constexpr std::size_t name_segment = 64;

enum ChunkType : std::uint8_t {
  uint8 = 1,
  uint16,
  uint32,
  uint64,
  int8,
  int16,
  int32,
  int64,
  float32,
  float64,
  character
};

inline std::size_t size_of(std::uint8_t type) {
  switch (type) {
    case uint8:
    case int8:
    case character: return 1;
    case uint16:
    case int16: return 2;
    case uint32:
    case int32:
    case float32: return 4;
    case uint64:
    case int64:
    case float64: return 8;
    default: return 0;
  }
}

}  // namespace pwcontact::detail::gsd
