// Uses the installed library through its public header only, compiled for the
// baseline x86-64 instruction set, and checks the answers it gets.
#include <pwcontact/pwcontact.hpp>

#if defined(__AVX__)
#error "built with AVX enabled: the package must not impose SIMD flags on its users"
#endif

#include <cmath>
#include <cstdio>
#include <vector>

namespace {

// Two spheres of radii 1 and 2 with centres 6 apart must be scaled by
// mu = 6 / (1 + 2) = 2 to touch: mu^2 = 4, lambda = 1/3.
constexpr double expected_mu2 = 4, expected_lambda = 1.0 / 3;
// A converged double solve of two spheres is exact to a few eps.
constexpr double tolerance = 1e-13;

bool close(double got, double expected) {
  return std::fabs(got - expected) <= tolerance * expected;
}

bool check(const char* path, double mu2, double lambda, pwcontact::Status status) {
  const bool good =
      close(mu2, expected_mu2) && close(lambda, expected_lambda) && pwcontact::is_valid(status);
  if (!good)
    std::printf("%s: mu2 %.17g lambda %.17g status %s, expected mu2 %.17g lambda %.17g\n", path,
                mu2, lambda, pwcontact::status_name(status), expected_mu2, expected_lambda);
  return good;
}

}  // namespace

int main() {
  const pwcontact::QuadraticForm q1 = pwcontact::sphere(1), q2 = pwcontact::sphere(2);
  const double r12[3] = {0, 4.8, 3.6};  // |r12| = 6

  bool good = true;
  const pwcontact::ContactResult<double> scalar =
      pwcontact::contact_function<double>(r12, q1.data(), q2.data());
  good &= check("scalar", scalar.mu2, scalar.lambda, scalar.status);

  // Longer than any register, so that full groups and a tail both run.
  const std::size_t n = 37;
  pwcontact::PairBatch<double> pairs;
  for (std::size_t i = 0; i < n; ++i) pairs.push_back(r12, q1.data(), q2.data());
  std::vector<double> mu2(n), lambda(n);
  std::vector<pwcontact::Status> status(n);
  const pwcontact::BatchReport report =
      pwcontact::contact_function_batch(pairs.view(), {mu2.data(), lambda.data(), status.data()});
  for (std::size_t i = 0; i < n; ++i) good &= check("batch", mu2[i], lambda[i], status[i]);
  good &= report.pairs == n && report.invalid == 0;

  std::printf("scalar mu2 %.17g; batch of %zu pairs on %s, %zu invalid: %s\n", scalar.mu2,
              report.pairs, pwcontact::isa_name(report.isa), report.invalid,
              good ? "correct" : "WRONG");
  return good ? 0 : 1;
}
