#include "scene/shape_json.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <map>
#include <stdexcept>

#include "number_text.hpp"

namespace pwcontact::detail {
namespace {

// A cursor over the text with the JSON grammar this needs.
class Json {
 public:
  explicit Json(const std::string& text) : text_(text) {}

  // {"key": value, ...}: the keys' string and number values.
  void object(std::map<std::string, std::string>& strings, std::map<std::string, double>& numbers) {
    expect('{');
    if (peek() == '}') {
      ++at_;
      return;
    }
    for (;;) {
      const std::string key = string();
      expect(':');
      const char c = peek();
      if (c == '"') {
        strings[key] = string();
      } else if (c == '-' || (c >= '0' && c <= '9')) {
        numbers[key] = number();
      } else {
        skip_value();
      }
      if (peek() == ',') {
        ++at_;
        continue;
      }
      expect('}');
      break;
    }
    if (peek() != '\0') fail("text after the object");
  }

 private:
  char peek() {
    while (at_ < text_.size() &&
           (text_[at_] == ' ' || text_[at_] == '\t' || text_[at_] == '\n' || text_[at_] == '\r'))
      ++at_;
    return at_ < text_.size() ? text_[at_] : '\0';
  }
  void expect(char c) {
    if (peek() != c) fail(std::string("expected '") + c + "'");
    ++at_;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument("its shape is not valid JSON (" + what + " at character " +
                                std::to_string(at_) + "): " + printable(text_.substr(0, 120)));
  }
  // A string with JSON's escapes (RFC 8259, section 7): \uXXXX as UTF-8 (a
  // surrogate pair as one character), the others as themselves; any other
  // escape, and a control character, refused ("Ellips\u006fid" was read as
  // "Ellipsu006fid", "Ellips\oid" taken).
  std::string string() {
    expect('"');
    std::string out;
    while (at_ < text_.size() && text_[at_] != '"') {
      const unsigned char c = static_cast<unsigned char>(text_[at_]);
      if (c < 0x20) fail("a control character in a string");
      if (c != '\\') {
        out += char(c);
        ++at_;
        continue;
      }
      if (++at_ >= text_.size()) break;
      const char e = text_[at_++];
      switch (e) {
        case '"': out += '"'; break;
        case '\\': out += '\\'; break;
        case '/': out += '/'; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          std::uint32_t code = hex4();
          if (code >= 0xd800 && code < 0xdc00) {  // a high surrogate: its low one follows
            if (at_ + 1 >= text_.size() || text_[at_] != '\\' || text_[at_ + 1] != 'u')
              fail("a lone surrogate in a \\u escape");
            at_ += 2;
            const std::uint32_t low = hex4();
            if (!(low >= 0xdc00 && low < 0xe000)) fail("a lone surrogate in a \\u escape");
            code = 0x10000 + ((code - 0xd800) << 10) + (low - 0xdc00);
          } else if (code >= 0xdc00 && code < 0xe000) {
            fail("a lone surrogate in a \\u escape");
          }
          append_utf8(out, code);
          break;
        }
        default: --at_; fail("an escape JSON does not have");
      }
    }
    if (at_ >= text_.size()) fail("an unterminated string");
    ++at_;
    return out;
  }
  std::uint32_t hex4() {
    std::uint32_t code = 0;
    for (int k = 0; k < 4; ++k, ++at_) {
      const char h = at_ < text_.size() ? text_[at_] : '\0';
      const int digit = h >= '0' && h <= '9'   ? h - '0'
                        : h >= 'a' && h <= 'f' ? h - 'a' + 10
                        : h >= 'A' && h <= 'F' ? h - 'A' + 10
                                               : -1;
      if (digit < 0) fail("a \\u escape without four hexadecimal digits");
      code = code * 16 + std::uint32_t(digit);
    }
    return code;
  }
  static void append_utf8(std::string& out, std::uint32_t code) {
    if (code < 0x80) {
      out += char(code);
    } else if (code < 0x800) {
      out += char(0xc0 | (code >> 6));
      out += char(0x80 | (code & 0x3f));
    } else if (code < 0x10000) {
      out += char(0xe0 | (code >> 12));
      out += char(0x80 | ((code >> 6) & 0x3f));
      out += char(0x80 | (code & 0x3f));
    } else {
      out += char(0xf0 | (code >> 18));
      out += char(0x80 | ((code >> 12) & 0x3f));
      out += char(0x80 | ((code >> 6) & 0x3f));
      out += char(0x80 | (code & 0x3f));
    }
  }
  // A number in JSON's grammar: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  // ("01", "1.", ".5", "+1" are not JSON numbers and are refused).
  double number() {
    const std::size_t start = at_;
    std::size_t k = at_;
    auto digits = [&] {
      const std::size_t from = k;
      while (k < text_.size() && text_[k] >= '0' && text_[k] <= '9') ++k;
      return k - from;
    };
    if (k < text_.size() && text_[k] == '-') ++k;
    const std::size_t integer_start = k;
    const std::size_t integer_digits = digits();
    if (integer_digits == 0 || (integer_digits > 1 && text_[integer_start] == '0'))
      fail("not a number in JSON's grammar");
    if (k < text_.size() && text_[k] == '.') {
      ++k;
      if (digits() == 0) fail("not a number in JSON's grammar");
    }
    if (k < text_.size() && (text_[k] == 'e' || text_[k] == 'E')) {
      ++k;
      if (k < text_.size() && (text_[k] == '+' || text_[k] == '-')) ++k;
      if (digits() == 0) fail("not a number in JSON's grammar");
    }
    double value = 0;
    const auto [end, error] = std::from_chars(text_.data() + start, text_.data() + k, value);
    if (error != std::errc() || end != text_.data() + k) fail("not a number");
    at_ = k;
    return value;
  }
  void skip_value() {
    const char c = peek();
    if (c == '{' || c == '[') {
      const char close = c == '{' ? '}' : ']';
      ++at_;
      int depth = 1;
      while (at_ < text_.size() && depth > 0) {
        const char d = text_[at_];
        if (d == '"') {
          string();
          continue;
        }
        if (d == '{' || d == '[') ++depth;
        if (d == '}' || d == ']') --depth;
        ++at_;
      }
      if (depth != 0) fail(std::string("an unterminated ") + close);
      return;
    }
    // true, false, null
    for (const char* word : {"true", "false", "null"})
      if (text_.compare(at_, std::char_traits<char>::length(word), word) == 0) {
        at_ += std::char_traits<char>::length(word);
        return;
      }
    fail("an unexpected value");
  }

  const std::string& text_;
  std::size_t at_ = 0;
};

double positive(const std::map<std::string, double>& numbers, const std::string& key,
                const std::string& shape) {
  const auto found = numbers.find(key);
  if (found == numbers.end())
    throw std::invalid_argument("its " + shape + " shape has no number '" + key + "'");
  if (!(found->second > 0) || !std::isfinite(found->second))
    throw std::invalid_argument("its " + shape + " shape has " + key + " = " +
                                detail::number_text(found->second) + ", not positive and finite");
  return found->second;
}

}  // namespace

ShapeAxes parse_shape(const std::string& json, bool two_dimensional) {
  if (json.empty()) throw std::invalid_argument("it has no shape (an empty type_shapes entry)");
  std::map<std::string, std::string> strings;
  std::map<std::string, double> numbers;
  Json(json).object(strings, numbers);
  const std::string type = strings.count("type") ? strings["type"] : "";
  if (type == "Sphere") {
    const double r = positive(numbers, "diameter", type) / 2;
    return {{r, r, r}};
  }
  if (type == "Ellipsoid") {
    const double a = positive(numbers, "a", type), b = positive(numbers, "b", type);
    if (two_dimensional) return {{a, b, a < b ? a : b}};
    return {{a, b, positive(numbers, "c", type)}};
  }
  // (Not among the shapes GSD's visualisation schema names, but the natural
  // spelling of a 2D ellipse: taken in a 2D scene, refused in a 3D one.)
  if (type == "Ellipse") {
    if (!two_dimensional)
      throw std::invalid_argument("its shape is an Ellipse, but the scene is three-dimensional");
    const double a = positive(numbers, "a", type), b = positive(numbers, "b", type);
    return {{a, b, a < b ? a : b}};
  }
  throw std::invalid_argument("its shape is '" + printable(type) +
                              "', not an ellipsoid (Ellipsoid, Sphere, or Ellipse in 2D)");
}

}  // namespace pwcontact::detail
