#include "scene/shape_json.hpp"

#include <charconv>
#include <cmath>
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
                                std::to_string(at_) + "): " + text_.substr(0, 120));
  }
  std::string string() {
    expect('"');
    std::string out;
    while (at_ < text_.size() && text_[at_] != '"') {
      if (text_[at_] == '\\') {
        if (++at_ >= text_.size()) break;
      }
      out += text_[at_++];
    }
    if (at_ >= text_.size()) fail("an unterminated string");
    ++at_;
    return out;
  }
  double number() {
    double value = 0;
    const char* begin = text_.data() + at_;
    const auto [end, error] = std::from_chars(begin, text_.data() + text_.size(), value);
    if (error != std::errc()) fail("not a number");
    at_ += std::size_t(end - begin);
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
  throw std::invalid_argument("its shape is '" + type +
                              "', not an ellipsoid (Ellipsoid, Sphere, or Ellipse in 2D)");
}

}  // namespace pwcontact::detail
