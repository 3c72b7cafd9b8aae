#include "pwcontact/reference.hpp"

#include <cmath>

namespace pwcontact {
namespace detail {
namespace {

// A floating-point expansion (Shewchuk 1997, "Adaptive precision
// floating-point arithmetic and fast robust geometric predicates"): a sum of
// doubles, nonoverlapping and in increasing order of magnitude (zeros may
// sit between), that represents a real number exactly. Its sign is that of
// its largest nonzero component, which is also its magnitude to within a
// factor 2.
class Expansion {
 public:
  // Adds b exactly (Grow-Expansion: a chain of error-free TwoSums).
  void add(double b) {
    for (int i = 0; i < size_; ++i) {
      const double sum = b + component_[i];
      const double b_virtual = sum - b;
      const double a_virtual = sum - b_virtual;
      component_[i] = (b - a_virtual) + (component_[i] - b_virtual);
      b = sum;
    }
    component_[size_++] = b;
  }

  // Adds sign x y exactly: the rounded product and its error (a fused
  // multiply-add is exact for it, barring underflow).
  void add_product(double x, double y, double sign) {
    const double p = x * y;
    add(sign * p);
    add(sign * std::fma(x, y, -p));
  }

  // Adds sign x y z exactly: x y = p + e exactly, then p z and e z.
  void add_product(double x, double y, double z, double sign) {
    const double p = x * y;
    const double e = std::fma(x, y, -p);
    add_product(p, z, sign);
    add_product(e, z, sign);
  }

  double leading() const {
    for (int i = size_ - 1; i >= 0; --i)
      if (component_[i] != 0) return component_[i];
    return 0;
  }

 private:
  double component_[24];  // the determinant's 5 products of 3 make 20
  int size_ = 0;
};

}  // namespace

bool positive_definite_exactly(const double a[6]) {
  if (!(a[0] > 0) || !(a[3] > 0) || !(a[5] > 0)) return false;  // NaN too
  // D Q D with D = diag(2^-k_i), k_i = floor(log2(a_ii) / 2): diagonal in
  // [1, 4), exact (scaling a subnormal up is exact too).
  int k[3];
  const int diagonal[3] = {0, 3, 5};
  for (int i = 0; i < 3; ++i) {
    const int e = std::ilogb(a[diagonal[i]]);
    k[i] = e >= 0 ? e / 2 : -((1 - e) / 2);  // floor(e / 2)
  }
  const double b00 = std::ldexp(a[0], -2 * k[0]), b11 = std::ldexp(a[3], -2 * k[1]),
               b22 = std::ldexp(a[5], -2 * k[2]);
  const double b01 = std::ldexp(a[1], -k[0] - k[1]), b02 = std::ldexp(a[2], -k[0] - k[2]),
               b12 = std::ldexp(a[4], -k[1] - k[2]);
  // An off-diagonal entry of 4 or more (or one that overflowed) exceeds the
  // geometric mean of its diagonal entries: a principal 2x2 minor is
  // negative. Below 4 every product of three entries is below 64.
  for (double b : {b01, b02, b12})
    if (!(std::abs(b) < 4)) return false;
  // Minors below this are within what underflowed off-diagonals could have
  // changed (a few 2^-1074 per product), or too small to tell: rejected.
  const double resolution = 0x1p-900;
  Expansion minor2;
  minor2.add_product(b00, b11, 1);
  minor2.add_product(b01, b01, -1);
  if (!(minor2.leading() > resolution)) return false;
  // det = b00 b11 b22 + 2 b01 b12 b02 - b00 b12^2 - b11 b02^2 - b22 b01^2
  Expansion det;
  det.add_product(b00, b11, b22, 1);
  det.add_product(2 * b01, b12, b02, 1);
  det.add_product(b00, b12, b12, -1);
  det.add_product(b11, b02, b02, -1);
  det.add_product(b22, b01, b01, -1);
  return det.leading() > resolution;
}

}  // namespace detail

template ContactResult<double> contact_function<double>(const double*, const double*, const double*,
                                                        const ReferenceOptions&);
template ContactResult<float> contact_function<float>(const float*, const float*, const float*,
                                                      const ReferenceOptions&);
template ContactGeometry<double> contact_geometry<double>(const double*, const double*,
                                                          const double*, double);
template ContactGeometry<float> contact_geometry<float>(const float*, const float*, const float*,
                                                        float);
}  // namespace pwcontact
