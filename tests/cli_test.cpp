// The command line end to end: the built `pwcontact` binary is run in a
// fresh temporary directory per test, its files, standard output, standard
// error and exit status checked.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <csignal>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "pwcontact/pwcontact.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;

// The status of a pair answered in full: ok from the x86 kernels, ok_fallback
// on the portable target (every pair on the reference path).
int ok_status() {
  return int(pwtest::on_portable_target() ? pwcontact::Status::ok_fallback : pwcontact::Status::ok);
}
std::string ok_text() { return std::to_string(ok_status()); }
using pwcontact::Status;

// What a run of the binary did.
struct Outcome {
  int exit_status = -1;
  std::string out, err;
};

// One output line: mu2 lambda status.
struct Result {
  double mu2, lambda;
  int status;
};

std::string quoted(const std::string& text) { return "'" + text + "'"; }

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string number_text(double x) {
  char text[32];
  return std::string(
      text, std::to_chars(text, text + sizeof text, x, std::chars_format::general, 17).ptr);
}

// A sphere of radius a as the 6 numbers of Q = a^2 I.
std::string sphere_text(double a) {
  const std::string a2 = number_text(a * a);
  return a2 + " 0 0 " + a2 + " 0 " + a2;
}

const std::string unit_sphere = sphere_text(1);

// Two spheres of radii a1 and a2 with centre 2 at c1 + r: mu = |r| / (a1 + a2).
struct Spheres {
  double a1, a2;
  std::array<double, 3> r;

  double distance() const { return std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]); }
  double mu() const { return distance() / (a1 + a2); }
  // The pair as an input line of `pwcontact contact`.
  std::string line() const {
    return number_text(r[0]) + " " + number_text(r[1]) + " " + number_text(r[2]) + " " +
           sphere_text(a1) + " " + sphere_text(a2) + "\n";
  }
};

std::string lines_of(const std::vector<Spheres>& cases) {
  std::string text;
  for (const Spheres& s : cases) text += s.line();
  return text;
}

// The pairs as input lines of `pwcontact contact`.
std::string pairs_text(const pwcontact::PairBatch<double>& pairs) {
  std::string text;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    double r12[3], q1[6], q2[6];
    pairs.get(i, r12, q1, q2);
    std::string line;
    for (double x : r12) line += number_text(x) + " ";
    for (double x : q1) line += number_text(x) + " ";
    for (double x : q2) line += number_text(x) + " ";
    line.back() = '\n';
    text += line;
  }
  return text;
}

std::vector<Result> parse_results(const std::string& text) {
  std::vector<Result> results;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream fields(line);
    std::string mu2, lambda;
    Result result{};
    fields >> mu2 >> lambda >> result.status;
    EXPECT_TRUE(fields && fields.peek() == EOF) << "output line: " << line;
    result.mu2 = std::strtod(mu2.c_str(), nullptr);  // strtod also reads "nan"
    result.lambda = std::strtod(lambda.c_str(), nullptr);
    results.push_back(result);
  }
  return results;
}

// The output lines as rows of numbers ("nan" is read as NaN), whatever the columns.
std::vector<std::vector<double>> parse_rows(const std::string& text) {
  std::vector<std::vector<double>> rows;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream fields(line);
    std::vector<double> row;
    for (std::string field; fields >> field;) row.push_back(std::strtod(field.c_str(), nullptr));
    rows.push_back(row);
  }
  return rows;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// Whitespace runs (line breaks of wrapped help text included) as one space.
std::string collapse_whitespace(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (!std::isspace(static_cast<unsigned char>(c)))
      out += c;
    else if (!out.empty() && out.back() != ' ')
      out += ' ';
  }
  return out;
}

// The number after the first `label` in `text`; NaN if there is none.
double number_after(const std::string& text, const std::string& label) {
  const std::size_t at = text.find(label);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + label.size(), nullptr);
}

// Suite names start with "cli" so that `ctest -R cli` selects exactly these tests.
class cli : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::path(::testing::TempDir()) / "pwcontact_cli.XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    directory_ = pattern;
  }
  void TearDown() override { fs::remove_all(directory_); }

  fs::path path(const std::string& name) const { return directory_ / name; }

  void write_file(const std::string& name, const std::string& text) const {
    std::ofstream(path(name), std::ios::binary) << text;
  }

  std::string read_file(const std::string& name) const {
    std::ifstream file(path(name), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(file), {});
  }

  // The files of the test directory, to check that nothing was left behind.
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(directory_))
      names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  // Runs `pwcontact <arguments>` in the test directory through the shell,
  // so that `arguments` may redirect standard input ("< pairs.txt"; it is
  // /dev/null otherwise) and `shell_prefix` may set variables or start a
  // pipe ("cat pairs.txt |").
  Outcome run(const std::string& arguments, const std::string& shell_prefix = "") const {
    const std::string command = "cd " + quoted(directory_.string()) + " && exec </dev/null && " +
                                shell_prefix + " " + quoted(PWCONTACT_CLI) + " " + arguments +
                                " >stdout.txt 2>stderr.txt";
    const int status = std::system(command.c_str());
    Outcome result;
    result.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    result.out = read_file("stdout.txt");
    result.err = read_file("stderr.txt");
    fs::remove(path("stdout.txt"));
    fs::remove(path("stderr.txt"));
    return result;
  }

  // The standard output of `contact` on `text` (written to pairs.txt), expecting success.
  std::string contact_output(const std::string& text) {
    write_file("pairs.txt", text);
    const Outcome result = run("contact pairs.txt");
    EXPECT_EQ(result.exit_status, 0) << result.err;
    return result.out;
  }
  std::vector<Result> contact(const std::string& text) {
    return parse_results(contact_output(text));
  }

 private:
  fs::path directory_;
};

// ---------------------------------------------------------------------------
// Results

TEST_F(cli, SpheresRoundTripThroughAFile) {
  // Two spheres: mu = |r| / (a1 + a2), lambda = a1 / (a1 + a2).
  const std::vector<Spheres> cases = {
      {1, 2, {6, 0, 0}}, {0.5, 1.5, {1, 2, 2}},        {3, 1, {0, 0, 1}},
      {1, 1, {0, 2, 0}}, {0.8, 1.7, {1.2, -0.7, 2.9}}, {2.5, 0.25, {-4, 3, -1}}};
  write_file("pairs.txt", lines_of(cases));

  const Outcome result = run("contact pairs.txt -o results.txt");
  ASSERT_EQ(result.exit_status, 0) << result.err;
  EXPECT_EQ(result.out, "");  // the results went to the file
  const std::vector<Result> results = parse_results(read_file("results.txt"));
  ASSERT_EQ(results.size(), cases.size());
  for (std::size_t i = 0; i < results.size(); ++i) {
    const Spheres& s = cases[i];
    const double mu = s.mu();
    // The batch path agrees with the reference path to 1e-13 relative (the
    // lane-by-lane tolerance), and 17 significant digits round-trip a double.
    EXPECT_NEAR(results[i].mu2, mu * mu, 1e-13 * mu * mu) << "pair " << i;
    EXPECT_NEAR(results[i].lambda, s.a1 / (s.a1 + s.a2), 1e-13) << "pair " << i;
    EXPECT_EQ(results[i].status, ok_status()) << "pair " << i;
  }
  // The summary on standard error counts the pairs.
  EXPECT_TRUE(contains(result.err, std::to_string(cases.size()) + " pairs")) << result.err;
}

TEST_F(cli, CommentsAndBlankLinesAreSkipped) {
  const std::string pair1 = "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n";
  const std::string pair2 = "0 3 0\t" + sphere_text(1) + "\t" + sphere_text(1) + "\n";
  const std::string plain = contact_output(pair1 + pair2);
  const std::string commented = contact_output("# r12 q1 q2\n\n   # indented comment\n" + pair1 +
                                               " \t \n#\n  " + pair2 + "\n# trailing comment");
  EXPECT_EQ(commented, plain);
  EXPECT_EQ(parse_results(plain).size(), 2u);
}

TEST_F(cli, NonFiniteNumbersAreAnsweredWithAStatusNotAnError) {
  const std::string good = "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n";
  const std::string& q = unit_sphere;
  const std::string text = good +                                   //
                           "nan 0 0 " + q + " " + q + "\n" +        //
                           "1 0 0 inf 0 0 1 0 1 " + q + "\n" +      //
                           "1 -Infinity 0 " + q + " " + q + "\n" +  //
                           "1 0 0 " + q + " +INF 0 0 1 0 1\n" +     //
                           "NaN 0 0 " + q + " " + q + "\n" +        //
                           "1e400 0 0 " + q + " " + q + "\n" +      // beyond double range
                           good;
  write_file("pairs.txt", text);
  const Outcome result = run("contact pairs.txt");
  ASSERT_EQ(result.exit_status, 0) << result.err;

  std::istringstream lines(result.out);
  std::vector<std::string> output;
  for (std::string line; std::getline(lines, line);) output.push_back(line);
  ASSERT_EQ(output.size(), 8u);
  EXPECT_EQ(output[0], "4 0.33333333333333331 " + ok_text());
  for (std::size_t i = 1; i <= 6; ++i)
    EXPECT_EQ(output[i], "nan nan " + std::to_string(int(Status::non_finite_input))) << i;
  EXPECT_EQ(output[7], output[0]);  // neighbours are unaffected
  EXPECT_TRUE(contains(result.err, "non_finite_input 6")) << result.err;
}

TEST_F(cli, MatricesThatAreNotPositiveDefiniteGetTheirStatus) {
  const std::vector<Result> results = contact("1 0 0 0 0 0 0 0 0 " + unit_sphere + "\n" + "1 0 0 " +
                                              unit_sphere + " -1 0 0 1 0 1\n");
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].status, int(Status::q1_not_positive_definite));
  EXPECT_EQ(results[1].status, int(Status::q2_not_positive_definite));
  EXPECT_TRUE(std::isnan(results[0].mu2) && std::isnan(results[1].lambda));
}

TEST_F(cli, LeadingPlusAndOtherNumberSpellingsAreAccepted) {
  const std::string q1 = "+1 0 0 1.0 0 1e0", q2 = "4 0 0 .4e1 0 4.";
  const std::vector<Result> results = contact("+6 -0 0 " + q1 + " " + q2 + "\r\n");
  ASSERT_EQ(results.size(), 1u);
  EXPECT_DOUBLE_EQ(results[0].mu2, 4);
}

// ---------------------------------------------------------------------------
// Overlap mode

TEST_F(cli, OverlapModeSaysWhetherSpheresOverlap) {
  // mu = |r| / (a1 + a2): 0, 0.3, 0.67, 0.9, 1.15, 1.3, 1.7 and 3, each at
  // least 0.1 from the cutoffs tried (1, 1.5 and 0.5).
  const std::vector<Spheres> cases = {
      {1, 1, {0, 0, 0}}, {1, 2, {0, 0, 0.9}},        {1, 2, {1.2, 1.6, 0}}, {0.5, 1.5, {0, 1.8, 0}},
      {2, 1, {2, 2, 2}}, {0.25, 0.75, {0, 0, -1.3}}, {1, 1, {3.4, 0, 0}},   {3, 2, {0, -15, 0}}};
  write_file("pairs.txt", lines_of(cases) + "nan 0 0 " + unit_sphere + " " + unit_sphere + "\n");

  for (const char* path : {"", "--precision mixed", "--precision float", "--scalar"}) {
    for (const double cutoff : {1.0, 1.5, 0.5}) {
      const std::string options =
          std::string(path) + (cutoff == 1 ? "" : " --cutoff " + number_text(cutoff));
      const Outcome result = run("contact --mode overlap " + options + " pairs.txt");
      ASSERT_EQ(result.exit_status, 0) << options << ": " << result.err;
      const std::vector<std::vector<double>> rows = parse_rows(result.out);
      ASSERT_EQ(rows.size(), cases.size() + 1) << options;
      std::size_t overlapping = 0;
      for (std::size_t i = 0; i < cases.size(); ++i) {
        const bool overlap = cases[i].mu() < cutoff;
        overlapping += overlap;
        ASSERT_EQ(rows[i].size(), 2u) << options << ", pair " << i;
        EXPECT_EQ(rows[i][0], overlap ? 1 : 0) << options << ", pair " << i;
        EXPECT_TRUE(pwcontact::is_valid(Status(rows[i][1]))) << options << ", pair " << i;
      }
      // An invalid pair does not overlap; its status says why.
      EXPECT_EQ(rows.back(), (std::vector<double>{0, double(Status::non_finite_input)})) << options;
      EXPECT_TRUE(contains(result.err, "mode overlap (cutoff " + number_text(cutoff) + ")"))
          << result.err;
      EXPECT_EQ(number_after(result.err, "overlapping "), double(overlapping)) << result.err;
    }
  }
}

// Random pairs moved along their centre lines so that mu^2 = 1 + epsilon,
// epsilon alternating in sign and running over 1e-3 ... 1e-8: mu^2 scales
// with |r12|^2, and the reference path gives the unmoved mu^2 to ~1e-15 on
// this family, far below the smallest epsilon.
struct NearTangentPairs {
  std::string text;
  std::vector<double> epsilon;
};

NearTangentPairs near_tangent_pairs(std::size_t n, std::uint64_t seed) {
  const double magnitudes[] = {1e-3, 1e-5, 1e-7, 1e-8};
  const pwcontact::PairBatch<double> pairs = pwcontact::random_pairs(n, seed);
  pwcontact::PairBatch<double> moved;
  NearTangentPairs out;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    double r12[3], q1[6], q2[6];
    pairs.get(i, r12, q1, q2);
    const double mu2 = pwcontact::contact_function<double>(r12, q1, q2).mu2;
    if (!(mu2 > 0)) continue;  // coincident centres stay overlapping wherever they are moved
    const double epsilon = (i % 2 ? 1 : -1) * magnitudes[(i / 2) % std::size(magnitudes)];
    pwcontact::scale_r12(r12, pwcontact::scale_to_mu2(mu2, 1 + epsilon));
    moved.push_back(r12, q1, q2);
    out.epsilon.push_back(epsilon);
  }
  out.text = pairs_text(moved);
  return out;
}

TEST_F(cli, OverlapModeIsExactBeyondItsBoundNearTangency) {
  const NearTangentPairs near = near_tangent_pairs(3000, 5);
  write_file("pairs.txt", near.text);
  struct Case {
    const char* options;
    double checked_from;  // |epsilon| from which the answer must be exact
  };
  // The documented bound is |mu^2 - 1| > 1e-9, so every epsilon here is
  // checked, with fixed iterations too (undecided pairs go to the reference
  // path). Float lanes see the input rounded to float, which moves mu^2 by
  // ~1e-7: only epsilon >= 1e-5 is fair for them.
  for (const Case& c : {Case{"", 1e-9}, Case{"--precision mixed", 1e-9}, Case{"--scalar", 1e-9},
                        Case{"--iterations 2", 1e-9}, Case{"--precision float", 1e-5}}) {
    const Outcome result = run(std::string("contact --mode overlap ") + c.options + " pairs.txt");
    ASSERT_EQ(result.exit_status, 0) << c.options << ": " << result.err;
    const std::vector<std::vector<double>> rows = parse_rows(result.out);
    ASSERT_EQ(rows.size(), near.epsilon.size()) << c.options;
    std::size_t overlapping = 0, wrong = 0, checked = 0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      ASSERT_TRUE(pwcontact::is_valid(Status(rows[i][1]))) << c.options << ", pair " << i;
      overlapping += rows[i][0] == 1;
      if (std::abs(near.epsilon[i]) < c.checked_from) continue;
      ++checked;
      wrong += (rows[i][0] == 1) != (near.epsilon[i] < 0);
    }
    EXPECT_EQ(wrong, 0u) << c.options << ": misclassified of " << checked;
    // The summary accounts for every pair, each decided exactly once.
    EXPECT_EQ(number_after(result.err, "overlapping "), double(overlapping)) << result.err;
    EXPECT_EQ(number_after(result.err, "decided by prefilter ") +
                  number_after(result.err, "by certificate ") +
                  number_after(result.err, "by the reference path "),
              double(rows.size()))
        << result.err;
  }
}

// ---------------------------------------------------------------------------
// Output columns

TEST_F(cli, GeometricOutputsOfTwoSpheresMatchTheClosedForm) {
  // Spheres with r12 along z: the spheres scaled by mu touch on the centre
  // line, so x0 - c1 = a1 / (a1 + a2) r12, the normal is r12 / |r12|, and
  // d mu^2 / d r12 = 2 r12 / (a1 + a2)^2; lambda = a1 / (a1 + a2). One pair
  // touches, one has sizes 1e4 apart.
  const std::vector<Spheres> cases = {{1, 2, {0, 0, 6}},
                                      {0.5, 1.5, {0, 0, -1}},
                                      {3, 1, {0, 0, 0.5}},
                                      {2, 2, {0, 0, 4}},
                                      {0.01, 100, {0, 0, 50}}};
  // Coincident centres (mu^2 = 0, no normal: 0 0 0) and an invalid pair (all nan).
  const Spheres coincident{1, 2, {0, 0, 0}};
  write_file("pairs.txt", lines_of(cases) + coincident.line() + "nan 0 0 " + unit_sphere + " " +
                              unit_sphere + "\n");
  // Not the canonical order: the columns follow the list.
  const std::string outputs = "--outputs gradient,mu2,normal,status,contact_point,lambda ";
  // Where each output starts on a line of the 12 columns.
  constexpr std::size_t gradient = 0, mu2 = 3, normal = 4, status = 7, contact_point = 8,
                        lambda = 11, columns = 12;
  // The radial guess solves spheres exactly; what remains is rounding: a few
  // eps in double, a few float eps in float (whose promise is 1e-5).
  struct Case {
    const char* options;
    double tolerance;
  };
  for (const Case& c :
       {Case{"", 1e-13}, Case{"--precision mixed", 1e-13}, Case{"--accuracy high", 1e-13},
        Case{"--scalar", 1e-13}, Case{"--precision float", 1e-6},
        Case{"--scalar --precision float", 1e-6}}) {
    const Outcome result = run("contact " + outputs + c.options + " pairs.txt");
    ASSERT_EQ(result.exit_status, 0) << c.options << ": " << result.err;
    const std::vector<std::vector<double>> rows = parse_rows(result.out);
    ASSERT_EQ(rows.size(), cases.size() + 2) << c.options;
    // Each 3-vector within tolerance times `scale`: its expected length, or
    // what it would be at |r12| = 1 when shorter (coincident centres: all 0).
    auto expect_vector = [&](const std::vector<double>& row, std::size_t column,
                             const std::array<double, 3>& expected, double scale,
                             const std::string& what) {
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(row[column + std::size_t(k)], expected[std::size_t(k)], c.tolerance * scale)
            << c.options << ", " << what << "[" << k << "]";
    };
    for (std::size_t i = 0; i <= cases.size(); ++i) {
      const Spheres& s = i < cases.size() ? cases[i] : coincident;
      const std::vector<double>& row = rows[i];
      ASSERT_EQ(row.size(), columns) << c.options << ", pair " << i;
      const double sum = s.a1 + s.a2, z = s.r[2], length = std::max(std::abs(z), 1.0);
      const std::string pair = "pair " + std::to_string(i);
      expect_vector(row, gradient, {0, 0, 2 * z / (sum * sum)}, 2 * length / (sum * sum),
                    pair + " gradient");
      EXPECT_NEAR(row[mu2], s.mu() * s.mu(), c.tolerance * std::max(s.mu() * s.mu(), 1.0))
          << c.options << ", " << pair;
      expect_vector(row, normal, {0, 0, z > 0 ? 1.0 : z < 0 ? -1.0 : 0.0}, 1, pair + " normal");
      EXPECT_TRUE(pwcontact::is_valid(Status(row[status]))) << c.options << ", " << pair;
      expect_vector(row, contact_point, {0, 0, s.a1 / sum * z}, length, pair + " contact_point");
      EXPECT_NEAR(row[lambda], s.a1 / sum, c.tolerance) << c.options << ", " << pair;
    }
    const std::vector<double>& invalid = rows.back();
    ASSERT_EQ(invalid.size(), columns) << c.options;
    for (std::size_t k = 0; k < invalid.size(); ++k)
      EXPECT_EQ(std::isnan(invalid[k]), k != status) << c.options << ", column " << k;
    EXPECT_EQ(invalid[status], double(Status::non_finite_input)) << c.options;
  }
}

TEST_F(cli, OnlyTheListedColumnsAreWritten) {
  write_file("pairs.txt", Spheres{1, 2, {6, 0, 0}}.line());
  EXPECT_EQ(run("contact --outputs status,mu2 pairs.txt").out, ok_text() + " 4\n");
  EXPECT_EQ(run("contact --outputs lambda pairs.txt").out, "0.33333333333333331\n");
  EXPECT_EQ(run("contact --outputs normal --scalar pairs.txt").out, "1 0 0\n");
}

TEST_F(cli, SummaryNamesTheSettingsAsResolved) {
  write_file("pairs.txt", Spheres{1, 2, {6, 0, 0}}.line() + Spheres{1, 1, {0, 1, 1}}.line());
  const Outcome defaults = run("contact pairs.txt");
  ASSERT_EQ(defaults.exit_status, 0) << defaults.err;
  EXPECT_TRUE(
      contains(defaults.err, "mode full, precision double, accuracy standard, formulation "))
      << defaults.err;
  EXPECT_FALSE(contains(defaults.err, "formulation auto")) << defaults.err;  // resolved
  EXPECT_TRUE(contains(defaults.err, "iterations auto")) << defaults.err;
  if (!pwtest::on_portable_target()) {  // (which makes no kernel evaluations)
    EXPECT_GE(number_after(defaults.err, "mean evaluations per pair "), 1) << defaults.err;
  }

  const Outcome chosen =
      run("contact --precision mixed --accuracy high --formulation log_odds --iterations 7 "
          "pairs.txt");
  ASSERT_EQ(chosen.exit_status, 0) << chosen.err;
  EXPECT_TRUE(
      contains(chosen.err, "mode full, precision mixed, accuracy high, formulation log_odds"))
      << chosen.err;
  EXPECT_TRUE(contains(chosen.err, "iterations 7")) << chosen.err;

  // A fixed count is exactly the evaluations every pair gets in the lanes.
  const Outcome fixed = run("contact --iterations 5 pairs.txt");
  if (!pwtest::on_portable_target()) {
    EXPECT_EQ(number_after(fixed.err, "mean evaluations per pair "), 5) << fixed.err;
  }

  const Outcome scalar = run("contact --scalar --mode overlap pairs.txt");
  ASSERT_EQ(scalar.exit_status, 0) << scalar.err;
  EXPECT_TRUE(contains(scalar.err, "reference path contact_function<double>: mode overlap"))
      << scalar.err;
  EXPECT_EQ(number_after(scalar.err, "by the reference path "), 2) << scalar.err;
}

// ---------------------------------------------------------------------------
// The paths and precisions agree

class cliRandomPairs : public cli {
 protected:
  void SetUp() override {
    cli::SetUp();
    write_file("pairs.txt", pairs_text(pwcontact::random_pairs(2000, 11)));
    reference_ = contact_file("");
  }
  std::vector<Result> contact_file(const std::string& options) {
    const Outcome result = run("contact " + options + " pairs.txt");
    EXPECT_EQ(result.exit_status, 0) << result.err;
    return parse_results(result.out);
  }
  // Every pair valid in both, mu2 within `mu2_relative`, lambda within `lambda_absolute`.
  void expect_agreement(const std::vector<Result>& results, double mu2_relative,
                        double lambda_absolute) const {
    ASSERT_EQ(results.size(), reference_.size());
    for (std::size_t i = 0; i < results.size(); ++i) {
      ASSERT_TRUE(pwcontact::is_valid(Status(results[i].status))) << "pair " << i;
      ASSERT_TRUE(pwcontact::is_valid(Status(reference_[i].status))) << "pair " << i;
      EXPECT_NEAR(results[i].mu2, reference_[i].mu2, mu2_relative * reference_[i].mu2) << i;
      EXPECT_NEAR(results[i].lambda, reference_[i].lambda, lambda_absolute) << i;
    }
  }
  std::vector<Result> reference_;  // the default: batch path in double
};

TEST_F(cliRandomPairs, FloatPrecisionAgreesWithDouble) {
  // The float batch path targets 1e-5 relative in mu2 against the reference
  // path on its own (float) input; rounding the 15 inputs to float adds
  // ~1e-7. Measured on 200,000 such pairs: 5.5e-7 for mu2, 5.6e-7 for lambda.
  expect_agreement(contact_file("--precision float"), 1e-5, 1e-5);
}

TEST_F(cliRandomPairs, ScalarReferencePathAgreesWithBatchPath) {
  // The lane-by-lane tolerance of the batch path against the reference path
  // (semi-axes in [0.5, 2]) is 1e-13 relative; measured: 1.7e-15. lambda,
  // the maximiser of a flat maximum, is less well determined than mu2, but
  // both paths end on Newton steps: measured 9e-16, allowed 1e-10.
  expect_agreement(contact_file("--scalar"), 1e-13, 1e-10);
}

TEST_F(cliRandomPairs, MixedPrecisionAndHighAccuracyAgreeWithDouble) {
  // Both promise double accuracy (high: better). Measured on 200,000 such
  // pairs against the default: mixed 1.3e-15 in mu2 and 9e-14 in lambda,
  // high 1e-15 and 0. The tolerances are those of the scalar comparison below.
  expect_agreement(contact_file("--precision mixed"), 1e-13, 1e-10);
  expect_agreement(contact_file("--accuracy high"), 1e-13, 1e-10);
  expect_agreement(contact_file("--accuracy high --precision mixed"), 1e-13, 1e-10);
}

TEST_F(cliRandomPairs, FixedIterationsAgreeWithAutomaticOnes) {
  // Pairs that miss the convergence check after N evaluations are answered
  // by the reference path, so any N gives the same accuracy.
  for (const char* iterations : {"1", "3", "40"})
    expect_agreement(contact_file(std::string("--iterations ") + iterations), 1e-13, 1e-10);
}

TEST_F(cliRandomPairs, DefaultsAreTheDocumentedOnes) {
  // The output with no option is byte for byte that of the defaults spelled out.
  const std::string plain = run("contact pairs.txt").out;
  EXPECT_EQ(run("contact --mode full --outputs mu2,lambda,status --precision double "
                "--iterations auto --accuracy standard --formulation auto pairs.txt")
                .out,
            plain);
  EXPECT_EQ(run("contact --iterations 0 pairs.txt").out, plain);  // 0 is auto too
}

TEST_F(cliRandomPairs, Mu2AloneAndTheLogOddsFormulationAgreeWithDouble) {
  // mu2 alone converges to a looser tolerance than with lambda (a third-order
  // error below 1e-11 f); measured 1e-15 against the default on 200,000 pairs.
  // log_odds is another iteration to the same maximum: measured 1.5e-15.
  for (const char* options : {"--outputs mu2", "--outputs mu2 --formulation log_odds"}) {
    const Outcome result = run(std::string("contact ") + options + " pairs.txt");
    ASSERT_EQ(result.exit_status, 0) << result.err;
    const std::vector<std::vector<double>> rows = parse_rows(result.out);
    ASSERT_EQ(rows.size(), reference_.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      ASSERT_EQ(rows[i].size(), 1u) << options;
      EXPECT_NEAR(rows[i][0], reference_[i].mu2, 1e-13 * reference_[i].mu2) << options << ", " << i;
    }
  }
}

TEST_F(cliRandomPairs, ResultsDoNotDependOnThreadCountOrInputKind) {
  const std::string one_thread = run("contact --threads 1 pairs.txt").out;
  EXPECT_EQ(run("contact --threads 2 pairs.txt").out, one_thread);
  EXPECT_EQ(run("contact --threads 2 < pairs.txt").out, one_thread);    // standard input
  EXPECT_EQ(run("contact --threads 2 - < pairs.txt").out, one_thread);  // '-' is standard input
  EXPECT_EQ(run("contact --threads 2", "cat pairs.txt |").out, one_thread);  // a pipe
}

TEST_F(cli, HighAccuracyBeatsTheDoubleFloorOnThePw85Family) {
  // Against the independent quad-precision values: plain double stops at
  // ~1e-11 on this family (eps times the condition of Q); high accuracy
  // promises 1e-13 in double and in mixed precision.
  const pwtest::ReferenceTable table = pwtest::load_reference_pairs();
  ASSERT_TRUE(table.error.empty()) << table.error;
  pwcontact::PairBatch<double> pairs;
  std::vector<long double> exact;
  for (const pwtest::ReferenceRecord& record : table.records)
    if (record.family == "pw85") {
      pairs.push_back(record.pair.r12.data(), record.pair.q1.data(), record.pair.q2.data());
      exact.push_back(record.mu2);
    }
  ASSERT_GT(pairs.size(), 0u);
  write_file("pairs.txt", pairs_text(pairs));

  auto max_error = [&](const std::string& options) {
    const Outcome result = run("contact " + options + " pairs.txt");
    EXPECT_EQ(result.exit_status, 0) << result.err;
    const std::vector<Result> results = parse_results(result.out);
    EXPECT_EQ(results.size(), exact.size()) << options;
    pwtest::MaxError error;
    for (std::size_t i = 0; i < std::min(results.size(), exact.size()); ++i)
      error.add(i, pwtest::relative_error(results[i].mu2, exact[i]));
    pwtest::print_measured("pw85 sample, " + options + ", mu2 relative error", error);
    return error.value;
  };
  max_error("--accuracy standard");  // printed for comparison
  EXPECT_LE(max_error("--accuracy high"), 1e-13);
  EXPECT_LE(max_error("--accuracy high --precision mixed"), 1e-13);
}

// ---------------------------------------------------------------------------
// Malformed input: exit status 2, the line number, and no output file

struct MalformedCase {
  const char* name;
  std::string line;
  const char* complaint;
};

// Names the case in test names and failure messages.
void PrintTo(const MalformedCase& malformed, std::ostream* out) { *out << malformed.name; }

class MalformedLine : public cli, public ::testing::WithParamInterface<MalformedCase> {};

TEST_P(MalformedLine, StopsWithTheLineNumberAndLeavesNoOutputFile) {
  const std::string good = "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n";
  // Line 4: after a comment and a blank line, which count as lines too.
  write_file("pairs.txt", good + "# comment\n\n" + GetParam().line + "\n" + good);

  for (const bool output_existed : {false, true}) {
    if (output_existed) write_file("results.txt", "earlier results\n");
    const Outcome result = run("contact pairs.txt -o results.txt");
    EXPECT_EQ(result.exit_status, 2);
    EXPECT_TRUE(contains(result.err, "pairs.txt:4:")) << result.err;
    EXPECT_TRUE(contains(result.err, GetParam().complaint)) << result.err;
    EXPECT_EQ(result.out, "");
    if (output_existed) {
      EXPECT_EQ(read_file("results.txt"), "earlier results\n");  // untouched
      fs::remove(path("results.txt"));
    }
    EXPECT_EQ(files(), std::vector<std::string>{"pairs.txt"});  // no partial or temporary file
  }

  // From standard input the message names <stdin>, and nothing is written.
  const Outcome from_stdin = run("contact < pairs.txt");
  EXPECT_EQ(from_stdin.exit_status, 2);
  EXPECT_TRUE(contains(from_stdin.err, "<stdin>:4:")) << from_stdin.err;
  EXPECT_EQ(from_stdin.out, "");
}

INSTANTIATE_TEST_SUITE_P(
    cli, MalformedLine,
    ::testing::Values(
        MalformedCase{"TooFewNumbers", "1 0 0 " + unit_sphere + " 1 0 0 1 0", "found 14"},
        MalformedCase{"TooManyNumbers", "1 0 0 " + unit_sphere + " " + unit_sphere + " 7",
                      "found 16"},
        MalformedCase{"TrailingGarbage", "1 0 0 " + unit_sphere + " 1 0 0 1 0 1.0x", "'1.0x'"},
        MalformedCase{"DecimalComma", "1,5 0 0 " + unit_sphere + " " + unit_sphere, "'1,5'"},
        MalformedCase{"SignAfterPlus", "+-1 0 0 " + unit_sphere + " " + unit_sphere, "'+-1'"},
        MalformedCase{"Word", "one 0 0 " + unit_sphere + " " + unit_sphere, "'one'"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST_F(cli, MalformedLineIsFoundDeepInABigInputReadInParallel) {
  // ~18 MB: more than one block when read from a pipe (16 MiB), many pieces
  // per thread when mapped from a file.
  std::string text = pairs_text(pwcontact::random_pairs(60000, 3));
  text += "1 2 3\n";
  write_file("pairs.txt", text);
  const Outcome from_file = run("contact --threads 2 pairs.txt");
  EXPECT_EQ(from_file.exit_status, 2);
  EXPECT_TRUE(contains(from_file.err, "pairs.txt:60001: expected 15 numbers, found 3"))
      << from_file.err;
  const Outcome from_pipe = run("contact --threads 2", "cat pairs.txt |");
  EXPECT_TRUE(contains(from_pipe.err, "<stdin>:60001:")) << from_pipe.err;
}

// ---------------------------------------------------------------------------
// Help, version and command-line errors

TEST_F(cli, HelpListsEveryStatusCodeAndEveryOption) {
  for (const char* arguments : {"--help", "-h", "help", "help contact", "contact --help"}) {
    const Outcome result = run(arguments);
    EXPECT_EQ(result.exit_status, 0) << arguments;
    const std::string help = collapse_whitespace(result.out);
    for (int s = 0; s < pwcontact::status_count; ++s) {
      const std::string row = std::to_string(s) + " " + pwcontact::status_name(Status(s)) + " " +
                              pwcontact::status_description(Status(s));
      EXPECT_TRUE(contains(help, row)) << arguments << ": no row '" << row << "'";
    }
    for (const char* option :
         {"--mode full|overlap", "--cutoff MU", "--outputs LIST", "--precision double|float|mixed",
          "--iterations N|auto", "--accuracy standard|high", "--formulation auto|newton|log_odds",
          "--threads N", "--isa auto|sse2|avx2|avx512", "--scalar", "-o, --output OUT"})
      EXPECT_TRUE(contains(help, option)) << arguments << ": " << option;
    for (const char* text :
         {"(default: full)", "(default: 1)", "(default: mu2,lambda,status)", "(default: double)",
          "(default: standard)", "(default: auto)",
          "mu2, lambda, status, contact_point, normal and gradient", "overlap status"})
      EXPECT_TRUE(contains(help, text)) << arguments << ": " << text;
  }
  const std::string pairs_help = collapse_whitespace(run("pairs --help").out);
  EXPECT_TRUE(contains(pairs_help, "--pairs N number of random pairs (default: 2000000)"))
      << pairs_help;
  const std::string demo_help = collapse_whitespace(run("demo --help").out);
  for (const char* text : {"--n N number of spheroids (default: 1000000)", "(default: 0.3)",
                           "--max-aspect A", "--seed S", "--cutoff MU"})
    EXPECT_TRUE(contains(demo_help, text)) << text << "\n" << demo_help;
  const std::string screen_help = collapse_whitespace(run("screen --help").out);
  for (const char* text :
       {"--box LX LY LZ [XY XZ YZ]", "--cutoff MU",
        "--format q|axes|ellipse|gsd|lammps-data|lammps-dump", "--with-mu2", "--frame N",
        "--columns NAME=COLUMN,...", "--outputs pairs|counts|neighbors", "--threads N",
        "-o, --output OUT", "x y z a b c qw qx qy qz", "ellipse: x y a b theta",
        ".lammpstrj lammps-dump"})
    EXPECT_TRUE(contains(screen_help, text)) << text << "\n" << screen_help;
}

TEST_F(cli, HelpLinesFitInATerminalOf80Columns) {
  for (const char* command :
       {"--help", "help contact", "help screen", "help pairs", "help demo", "help mc"}) {
    const Outcome help = run(command);
    ASSERT_EQ(help.exit_status, 0) << command;
    std::istringstream lines(help.out);
    int number = 0;
    for (std::string line; std::getline(lines, line);) {
      ++number;
      EXPECT_LE(line.size(), 79u) << command << ", line " << number << ": " << line;
    }
  }
}

TEST_F(cli, VersionIsPrinted) {
  const Outcome result = run("--version");
  EXPECT_EQ(result.exit_status, 0);
  // "pwcontact MAJOR.MINOR.PATCH"
  const std::string prefix = "pwcontact ";
  ASSERT_EQ(result.out.compare(0, prefix.size(), prefix), 0) << result.out;
  const std::string version = result.out.substr(prefix.size());
  EXPECT_EQ(std::count(version.begin(), version.end(), '.'), 2) << version;
  EXPECT_EQ(version.find_first_not_of("0123456789."), version.size() - 1) << version;
  EXPECT_EQ(version.back(), '\n');
}

class UsageError : public cli, public ::testing::WithParamInterface<const char*> {};

TEST_P(UsageError, ExitsWithStatus2AndShowsTheUsage) {
  write_file("a.txt", "");
  write_file("b.txt", "");
  const Outcome result = run(GetParam());
  EXPECT_EQ(result.exit_status, 2);
  EXPECT_TRUE(contains(result.err, "Usage: pwcontact")) << result.err;
  EXPECT_EQ(result.out, "");
}

INSTANTIATE_TEST_SUITE_P(
    cli, UsageError,
    ::testing::Values(
        "", "frobnicate", "--frobnicate", "help frobnicate", "contact --frobnicate",
        "contact --threads", "contact --threads many", "contact --threads -1",
        "contact --iterations 1001", "contact --precision half", "contact --isa avx9",
        "contact --scalar=yes", "contact a.txt b.txt", "contact --scalar --iterations 2 a.txt",
        "pairs --pairs 0", "pairs extra", "demo extra", "demo --n 0", "demo --packing 1",
        "demo --max-aspect 0.5", "screen --box 1 2", "screen --box 1 2 0 a.txt",
        "screen --box 1 2 x a.txt", "screen --box=1,2 a.txt", "screen --box=1,2,3,4 a.txt",
        "screen --box=1,x,3 a.txt", "screen --box=1,2,0 a.txt", "screen --box= a.txt",
        "screen --cutoff 0 a.txt", "screen --format xyz a.txt",
        // A cutoff whose square is not a normal double (mu^2 is compared with it)
        "screen --cutoff 1e-200 a.txt", "screen --cutoff 1e200 a.txt",
        "contact --mode overlap --cutoff 1e-160 a.txt", "demo --cutoff 1e-300",
        "screen a.txt b.txt",
        // Scene formats: what each takes
        "screen --frame 1 a.txt", "screen --frame x b.gsd", "screen --columns x=c_x[1] a.txt",
        "screen --columns foo=c_x[1] b.dump", "screen --columns x= b.dump", "screen --format gsd",
        "screen --box 1 1 1 b.gsd", "screen --format ellipse --box 1 1 1 1 a.txt",
        "screen --box 1 1 1 1 a.txt", "screen --box 10 10 10 0.5 0 a.txt",
        "screen --box=1,1,1,1,1,1,1 a.txt", "screen --box 10 10 10 0 0 inf a.txt",
        "screen --outputs all a.txt", "screen --outputs pairs,counts a.txt",
        "screen --write-gsd o.gsd a.txt", "screen --write-gsd= b.gsd", "screen --columns= b.dump",
        // --version and --help take nothing after them (both were ignored)
        "--version extra", "-h contact", "--help screen",
        // Bad values of the options of the answer and the arithmetic
        "contact --mode both", "contact --precision auto", "contact --precision",
        "contact --iterations automatic", "contact --iterations -1", "contact --accuracy best",
        "contact --formulation halley", "contact --mode overlap --cutoff 0",
        "contact --mode overlap --cutoff -1", "contact --mode overlap --cutoff inf",
        "contact --mode overlap --cutoff nan", "contact --mode overlap --cutoff 1e999",
        "contact --mode overlap --cutoff 1x", "contact --outputs mu2,foo",
        "contact --outputs mu2,,lambda", "contact --outputs ''", "contact --outputs mu2,mu2",
        "contact --outputs overlap", "pairs --iterations never",
        // Combinations that do not apply
        "contact --accuracy high --precision float a.txt",
        "pairs --accuracy high --precision float", "contact --mode overlap --outputs mu2 a.txt",
        "contact --mode overlap --outputs overlap,status a.txt",
        "contact --mode overlap --accuracy standard a.txt", "contact --cutoff 2 a.txt",
        "contact --mode full --cutoff 1 a.txt", "contact --scalar --precision mixed a.txt",
        "contact --scalar --accuracy high a.txt", "contact --scalar --formulation newton a.txt",
        "contact --scalar --isa auto a.txt",
        // mc
        "mc --n 0", "mc --packing 0.7", "mc --packing 0", "mc --sweeps 0", "mc extra"));

TEST_F(cli, OptionsThatDoNotApplyAreRefusedWithTheReason) {
  write_file("a.txt", "");
  struct Case {
    const char* arguments;
    const char* reason;
  };
  for (const Case& c :
       {Case{"--accuracy high --precision float", "needs --precision double or mixed"},
        Case{"--mode overlap --outputs mu2", "--outputs applies to --mode full"},
        Case{"--mode overlap --accuracy high", "--accuracy applies to mu^2 (--mode full)"},
        Case{"--cutoff 2", "--cutoff applies to --mode overlap"},
        Case{"--scalar --precision mixed", "--precision mixed applies to the batch path"},
        Case{"--scalar --formulation log_odds", "--formulation applies to the batch path"},
        Case{"--outputs mu2,status,mu2", "mu2 is listed twice"},
        Case{"--mode overlap --cutoff 0", "'0' is not a positive finite number"},
        Case{"--precision half", "'half' is not double, float or mixed"}}) {
    const Outcome result = run(std::string("contact ") + c.arguments + " a.txt");
    EXPECT_EQ(result.exit_status, 2) << c.arguments;
    EXPECT_TRUE(contains(result.err, c.reason)) << c.arguments << ": " << result.err;
  }
}

TEST_F(cli, OutputThroughASymbolicLinkOrToADeviceIsWrittenInPlace) {
  write_file("pairs.txt", "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n");
  fs::create_directory(path("kept"));
  write_file("kept/results.txt", "earlier results\n");
  fs::create_symlink("kept/results.txt", path("link.txt"));
  ASSERT_EQ(run("contact pairs.txt -o link.txt").exit_status, 0);
  EXPECT_TRUE(fs::is_symlink(path("link.txt")));  // the link is kept, its target replaced
  EXPECT_EQ(read_file("kept/results.txt"), "4 0.33333333333333331 " + ok_text() + "\n");

  // Renaming a finished file over /dev/null would replace the device.
  ASSERT_EQ(run("contact pairs.txt -o /dev/null").exit_status, 0);
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

TEST_F(cli, InputAndOutputErrorsExitWithStatus1) {
  const Outcome missing_input = run("contact missing.txt");
  EXPECT_EQ(missing_input.exit_status, 1);
  EXPECT_TRUE(contains(missing_input.err, "missing.txt")) << missing_input.err;

  write_file("pairs.txt", "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n");
  const Outcome missing_directory = run("contact pairs.txt -o no/such/directory/results.txt");
  EXPECT_EQ(missing_directory.exit_status, 1);
  EXPECT_TRUE(contains(missing_directory.err, "cannot write no/such/directory/results.txt"))
      << missing_directory.err;
}

TEST_F(cli, BadInstructionSetInTheEnvironmentIsAUsageError) {
  write_file("a.txt", "");
  const Outcome result = run("contact a.txt", "PWCONTACT_ISA=avx9");
  EXPECT_EQ(result.exit_status, 2);
  EXPECT_TRUE(contains(result.err, "PWCONTACT_ISA=avx9")) << result.err;
}

TEST_F(cli, InstructionSetsTheCpuLacksAreAUsageError) {
  write_file("a.txt", "");
  int lacking = 0;
  for (pwcontact::Isa isa : {pwcontact::Isa::sse2, pwcontact::Isa::avx2, pwcontact::Isa::avx512})
    if (!pwcontact::isa_supported(isa)) {
      ++lacking;
      const Outcome result =
          run(std::string("contact --isa ") + pwcontact::isa_name(isa) + " a.txt");
      EXPECT_EQ(result.exit_status, 2);
      EXPECT_TRUE(contains(result.err, "does not support")) << result.err;
    }
  if (lacking == 0) GTEST_SKIP() << "this CPU runs every instruction set";
}

// ---------------------------------------------------------------------------
// The pairs demo and the demo

TEST_F(cli, PairsReportsThroughputAndAccuracy) {
  for (const char* precision : {"double", "float", "mixed"}) {
    const Outcome result =
        run(std::string("pairs --pairs 3000 --iterations auto --precision ") + precision);
    ASSERT_EQ(result.exit_status, 0) << result.err;
    for (const char* word : {"pairs/s", "speed-up", "fallbacks", "p99.9", "median"})
      EXPECT_TRUE(contains(result.out, word)) << precision << ": " << word;
    // Each path's accuracy target against the reference path (see the
    // float and scalar agreement tests above).
    EXPECT_LE(number_after(result.out, "max "), precision == std::string("float") ? 1e-5 : 1e-13)
        << result.out;
  }
}

TEST_F(cli, DemoScreensASceneAndReportsEveryStage) {
  const Outcome result = run("demo --n 20000 --seed 3");
  ASSERT_EQ(result.exit_status, 0) << result.err;
  for (const char* word : {"20000 spheroids", "periodic box", "candidate pairs", "found", "cells",
                           "candidates and prefilters", "compaction", "solve", "sorting", "total"})
    EXPECT_TRUE(contains(result.out, word)) << word << "\n" << result.out;
  // The same scene and the same pairs with one thread.
  const Outcome one = run("demo --n 20000 --seed 3 --threads 1");
  ASSERT_EQ(one.exit_status, 0) << one.err;
  EXPECT_EQ(number_after(one.out, "found "), number_after(result.out, "found "));
  EXPECT_GT(number_after(result.out, "found "), 1000) << "packing fraction 0.3: many overlaps";
}

// ---------------------------------------------------------------------------
// screen

TEST_F(cli, ScreenWritesThePairsSortedWithTheirMu2) {
  // Spheres of radius 1: 0-1 at distance 1.5 (mu = 0.75), 0-2 across the
  // periodic boundary at distance 1 (mu = 0.5), 1-2 across it at 2.5
  // (mu = 1.25), 1-3 at distance 3 (mu = 1.5); the others farther.
  write_file("spheres.txt",
             "# x y z q\n"
             "0.5 5 5  1 0 0 1 0 1\n"
             "2 5 5  1 0 0 1 0 1\n"
             "\n"
             "9.5 5 5  1 0 0 1 0 1\n"
             "5 5 5  1 0 0 1 0 1\n");
  const Outcome overlaps = run("screen --box 10 10 10 spheres.txt");
  ASSERT_EQ(overlaps.exit_status, 0) << overlaps.err;
  EXPECT_EQ(overlaps.out, "0 1\n0 2\n");
  EXPECT_TRUE(contains(overlaps.err, "candidate pairs")) << overlaps.err;
  const Outcome open = run("screen spheres.txt");
  EXPECT_EQ(open.out, "0 1\n") << "without --box, 0 and 2 are 9 apart";
  // The --opt=value form of --box (once silently ignored: open boundaries).
  const Outcome inline_box = run("screen --box=10,10,10 spheres.txt");
  ASSERT_EQ(inline_box.exit_status, 0) << inline_box.err;
  EXPECT_EQ(inline_box.out, overlaps.out);
  const Outcome skin = run("screen --box 10 10 10 --cutoff 1.6 --with-mu2 spheres.txt");
  ASSERT_EQ(skin.exit_status, 0) << skin.err;
  EXPECT_EQ(skin.out, "0 1 0.5625\n0 2 0.25\n1 2 1.5625\n1 3 2.25\n");
}

TEST_F(cli, ScreenReadsSemiAxesAndQuaternions) {
  // A needle (0.1, 0.1, 2) along z, and a sphere of radius 0.5 at z = 2.4:
  // overlapping (mu^2 = (2.4 / 2.5)^2); rotated by 90 degrees about x the
  // needle lies along y and the pair is apart.
  write_file("axes.txt", "0 0 0  0.1 0.1 2  1 0 0 0\n0 0 2.4  0.5 0.5 0.5  1 0 0 0\n");
  EXPECT_EQ(run("screen --format axes axes.txt").out, "0 1\n");
  write_file("turned.txt",
             "0 0 0  0.1 0.1 2  0.7071067811865476 0.7071067811865476 0 0\n"
             "0 0 2.4  0.5 0.5 0.5  1 0 0 0\n");
  EXPECT_EQ(run("screen --format axes turned.txt").out, "");
}

TEST_F(cli, ScreenWritesCountsAndNeighboursPerParticle) {
  // The scene of the test above: pairs 0-1 (mu^2 0.5625), 0-2 (0.25), 1-2
  // (1.5625), 1-3 (2.25) with cutoff 1.6.
  write_file("spheres.txt",
             "0.5 5 5  1 0 0 1 0 1\n2 5 5  1 0 0 1 0 1\n9.5 5 5  1 0 0 1 0 1\n"
             "5 5 5  1 0 0 1 0 1\n20 20 20  1 0 0 1 0 1\n");
  const std::string common = "screen --box 30 30 30 --cutoff 1.6 spheres.txt";
  // (In a 30 box 0-2 are 9 apart: pairs 0-1 and 1-3 only; particle 4 alone.)
  EXPECT_EQ(run(common).out, "0 1\n1 3\n");
  EXPECT_EQ(run(common + " --outputs counts").out, "1\n2\n0\n1\n0\n");
  EXPECT_EQ(run(common + " --outputs neighbors").out, "1\n0 3\n\n1\n\n");
  const std::string periodic = "screen --box 10 10 10 --cutoff 1.6 --with-mu2 spheres.txt";
  write_file("spheres.txt",
             "0.5 5 5  1 0 0 1 0 1\n2 5 5  1 0 0 1 0 1\n9.5 5 5  1 0 0 1 0 1\n"
             "5 5 5  1 0 0 1 0 1\n");
  EXPECT_EQ(run(periodic + " --outputs counts").out, "2\n3\n2\n1\n");
  EXPECT_EQ(run(periodic + " --outputs neighbors").out,
            "1 0.5625 2 0.25\n0 0.5625 2 1.5625 3 2.25\n0 0.25 1 1.5625\n1 2.25\n");
}

TEST_F(cli, ScreenTakesTiltedBoxesInTheHoomdConvention) {
  // Spheres of radius 0.4 at (1, -4.5, 0) and (6, 5, 0): with tilt xy 0.5
  // the lattice vector (XY LY, LY, 0) = (5, 10, 0) brings the second to
  // (1, -5, 0), 0.5 away (mu = 0.625); without the tilt they are far apart.
  write_file("two.txt", "1 -4.5 0  0.16 0 0 0.16 0 0.16\n6 5 0  0.16 0 0 0.16 0 0.16\n");
  // mu^2 = (0.5 / 0.8)^2, to the rounding of the image (fractional
  // coordinates times the box: a few eps of the box length in r).
  double mu2 = 0;
  ASSERT_EQ(std::sscanf(run("screen --box 10 10 10 0.5 0 0 --with-mu2 two.txt").out.c_str(),
                        "0 1 %lf", &mu2),
            1);
  EXPECT_NEAR(mu2, 0.390625, 1e-14);
  EXPECT_EQ(run("screen --box=10,10,10,0.5,0,0 two.txt").out, "0 1\n");
  EXPECT_EQ(run("screen --box 10 10 10 two.txt").out, "");
  const Outcome thin = run("screen --box 10 10 10 3 0 0 --cutoff 12 two.txt");
  EXPECT_EQ(thin.exit_status, 2);
  EXPECT_TRUE(contains(thin.err, "too small")) << thin.err;
}

TEST_F(cli, ScreenReadsEllipsesInAPlaneWithTheirExactContactFunction) {
  // Ellipses a = 2, b = 0.5 on the x axis, 3 apart: aligned with the line
  // of centres mu = 3 / (2 + 2); the second turned by 90 degrees, mu =
  // 3 / (2 + 0.5) (a principal axis of both along r: mu = d / (r1 + r2)).
  write_file("ellipses.txt",
             "0 0 2 0.5 0\n3 0 2 0.5 0\n0 5 2 0.5 0\n3 5 2 0.5 1.5707963267948966\n");
  const Outcome result = run("screen --format ellipse --cutoff 1.5 --with-mu2 ellipses.txt");
  ASSERT_EQ(result.exit_status, 0) << result.err;
  const auto lines = split_lines(result.out);
  ASSERT_EQ(lines.size(), 2u) << result.out;
  double mu2[2];
  ASSERT_EQ(std::sscanf(lines[0].c_str(), "0 1 %lf", &mu2[0]), 1) << lines[0];
  ASSERT_EQ(std::sscanf(lines[1].c_str(), "2 3 %lf", &mu2[1]), 1) << lines[1];
  // (the turned ellipse's Q carries the rounding of cos(pi/2): a few eps)
  EXPECT_NEAR(mu2[0], 0.5625, 4e-16);
  EXPECT_NEAR(mu2[1], 1.44, 1e-15);
  EXPECT_TRUE(contains(result.err, "4 ellipses")) << result.err;
  // A two-dimensional periodic box: LX LY [XY]; the first pair across the
  // tilted boundary as in the test above.
  write_file("plane.txt", "1 -4.5 0.4 0.4 0\n6 5 0.4 0.4 0\n");
  EXPECT_EQ(run("screen --format ellipse --box 10 10 0.5 plane.txt").out, "0 1\n");
  EXPECT_EQ(run("screen --format ellipse --box 10 10 plane.txt").out, "");
  const Outcome zero =
      run("screen --format ellipse plane.txt", "printf '0 0 1 0 0\\n' >> plane.txt &&");
  EXPECT_EQ(zero.exit_status, 2);
  EXPECT_TRUE(contains(zero.err, "ellipse 2 (line 3)")) << zero.err;
}

TEST_F(cli, ScreenReadsGsdAndLammpsFilesByTheirNames) {
  const std::string data = PWCONTACT_TEST_DATA;
  // The command line's pairs are the library's (which scene_files_test holds
  // to the brute force) for each format, chosen from the name.
  auto library_pairs = [](const pwcontact::Scene& scene, double cutoff) {
    pwcontact::ScreenedPairs pairs;
    pwcontact::ScreenOptions options;
    options.cutoff = cutoff;
    pwcontact::screen_pairs(scene.particles, scene.box, options, pairs);
    std::string text;
    for (std::size_t k = 0; k < pairs.size(); ++k)
      text += std::to_string(pairs.i[k]) + " " + std::to_string(pairs.j[k]) + "\n";
    return text;
  };
  const std::string gsd = data + "/hoomd_triclinic.gsd";
  const Outcome from_gsd = run("screen --cutoff 1.2 " + quoted(gsd));
  ASSERT_EQ(from_gsd.exit_status, 0) << from_gsd.err;
  EXPECT_EQ(from_gsd.out, library_pairs(pwcontact::read_gsd(gsd), 1.2));
  EXPECT_GT(from_gsd.out.size(), 50u);
  EXPECT_TRUE(contains(from_gsd.err, "(gsd, frame 0 of 1)")) << from_gsd.err;
  EXPECT_TRUE(contains(from_gsd.err, "tilts xy 0.3 xz -0.2 yz 0.1")) << from_gsd.err;
  const std::string ellipses = data + "/hoomd_ellipses_2d.gsd";
  const Outcome from_2d = run("screen " + quoted(ellipses));
  ASSERT_EQ(from_2d.exit_status, 0) << from_2d.err;
  EXPECT_EQ(from_2d.out, library_pairs(pwcontact::read_gsd(ellipses), 1));
  EXPECT_TRUE(contains(from_2d.err, "two-dimensional periodic box 9 x 8, tilt xy 0.25"))
      << from_2d.err;
  const std::string lammps = data + "/lammps_triclinic.data";
  const Outcome from_data = run("screen --cutoff 1.3 " + quoted(lammps));
  ASSERT_EQ(from_data.exit_status, 0) << from_data.err;
  EXPECT_EQ(from_data.out, library_pairs(pwcontact::read_lammps_data(lammps), 1.3));
  // A dump's frame, with a compute's columns mapped.
  const std::string dump = data + "/lammps_triclinic.dump";
  pwcontact::LammpsColumns columns;
  for (int k = 0; k < 3; ++k) columns.shape[k] = "c_s[" + std::to_string(k + 1) + "]";
  for (int k = 0; k < 4; ++k) columns.quaternion[k] = "c_q[" + std::to_string(k + 1) + "]";
  const std::string mapped =
      " --columns shapex=c_s[1],shapey=c_s[2],shapez=c_s[3],quatw=c_q[1],quati=c_q[2],"
      "quatj=c_q[3],quatk=c_q[4] ";
  const Outcome from_dump = run("screen --frame 1 --cutoff 1.3" + mapped + quoted(dump));
  ASSERT_EQ(from_dump.exit_status, 0) << from_dump.err;
  EXPECT_EQ(from_dump.out, library_pairs(pwcontact::read_lammps_dump(dump, 1, columns), 1.3));
  EXPECT_TRUE(contains(from_dump.err, "(lammps-dump, frame 1 of 3)")) << from_dump.err;
  // The format named whatever the file's name.
  fs::copy_file(gsd, path("scene.bin"));
  EXPECT_EQ(run("screen --format gsd --cutoff 1.2 scene.bin").out, from_gsd.out);
}

TEST_F(cli, ScreenWritesTheCountsBackAsAGsdFrame) {
  const std::string gsd = std::string(PWCONTACT_TEST_DATA) + "/hoomd_triclinic.gsd";
  const Outcome result =
      run("screen --cutoff 1.2 --outputs counts --write-gsd out.gsd " + quoted(gsd));
  ASSERT_EQ(result.exit_status, 0) << result.err;
  EXPECT_TRUE(contains(result.err, "log/particles/overlaps to out.gsd")) << result.err;
  // The frame as it was: the same scene read back.
  const pwcontact::Scene original = pwcontact::read_gsd(gsd),
                         written = pwcontact::read_gsd(path("out.gsd"));
  ASSERT_EQ(written.particles.size(), original.particles.size());
  EXPECT_EQ(written.box.tilt, original.box.tilt);
  for (std::size_t i = 0; i < original.particles.size(); ++i)
    for (int k = 0; k < 6; ++k)
      EXPECT_EQ(written.particles.q(k)[i], original.particles.q(k)[i]) << i;
  // The counts, as python3-gsd (an independent reader) sees them.
  write_file("log.py",
             "import gsd.hoomd\n"
             "with gsd.hoomd.open('out.gsd', 'rb') as t:\n"
             "    print('\\n'.join(str(x) for x in t.read_frame(0).log['particles/overlaps']))\n");
  if (std::system("/usr/bin/python3 -c 'import gsd.hoomd' 2>/dev/null") == 0) {
    const std::string command = "cd " + quoted(path(".")) + " && /usr/bin/python3 log.py > log.txt";
    ASSERT_EQ(std::system(command.c_str()), 0);
    EXPECT_EQ(read_file("log.txt"), result.out);
  }
  // Chunk names of 64 characters and more, as HOOMD-blue logs its
  // quantities (file layer 2.0 has no limit): copied into the written frame.
  // Was: refused, after the pairs had gone to standard output.
  write_file("long.py",
             "import gsd.hoomd, numpy as np, sys\n"
             "key = 'md/compute/ThermodynamicQuantities/translational_kinetic_energy'\n"
             "if sys.argv[1] == 'write':\n"
             "    s = gsd.hoomd.Snapshot(); s.particles.N = 2\n"
             "    s.configuration.box = [10, 10, 10, 0, 0, 0]\n"
             "    s.particles.type_shapes = [{'type': 'Sphere', 'diameter': 1.0}]\n"
             "    s.particles.position = [[0, 0, 0], [0.5, 0, 0]]\n"
             "    s.log[key] = np.array([1.5])\n"
             "    with gsd.hoomd.open('long.gsd', 'wb') as t: t.append(s)\n"
             "else:\n"
             "    with gsd.hoomd.open('long_out.gsd', 'rb') as t:\n"
             "        f = t.read_frame(0)\n"
             "        print(f.log[key][0], f.log['particles/overlaps'].tolist())\n");
  if (std::system("/usr/bin/python3 -c 'import gsd.hoomd' 2>/dev/null") == 0) {
    const std::string in_dir = "cd " + quoted(path(".")) + " && /usr/bin/python3 long.py ";
    ASSERT_EQ(std::system((in_dir + "write").c_str()), 0);
    const Outcome long_names = run("screen --outputs counts --write-gsd long_out.gsd long.gsd");
    ASSERT_EQ(long_names.exit_status, 0) << long_names.err;
    ASSERT_EQ(std::system((in_dir + "read > long.txt").c_str()), 0);
    EXPECT_EQ(read_file("long.txt"), "1.5 [1, 1]\n");
  }
  // A failed run writes neither output.
  std::ifstream in(gsd, std::ios::binary);
  const std::string bytes(std::istreambuf_iterator<char>(in), {});
  write_file("cut.gsd", bytes.substr(0, bytes.size() / 2));
  const Outcome cut = run("screen -o counts.txt --outputs counts --write-gsd cut_out.gsd cut.gsd");
  EXPECT_EQ(cut.exit_status, 2);
  EXPECT_FALSE(fs::exists(path("cut_out.gsd")));
  EXPECT_FALSE(fs::exists(path("counts.txt")));
}

TEST_F(cli, MalformedSimulationFilesStopTheRunNamingWhatIsWrong) {
  const std::string data = PWCONTACT_TEST_DATA;
  // A truncated GSD file: exit 2, nothing written.
  std::ifstream in(data + "/hoomd_triclinic.gsd", std::ios::binary);
  const std::string bytes(std::istreambuf_iterator<char>(in), {});
  write_file("cut.gsd", bytes.substr(0, bytes.size() * 2 / 3));
  const Outcome cut = run("screen -o pairs.txt cut.gsd");
  EXPECT_EQ(cut.exit_status, 2);
  EXPECT_TRUE(contains(cut.err, "cut.gsd: truncated")) << cut.err;
  EXPECT_FALSE(fs::exists(path("pairs.txt")));
  // A dump without the shapes under their usual names.
  const Outcome unnamed = run("screen -o pairs.txt " + quoted(data + "/lammps_triclinic.dump"));
  EXPECT_EQ(unnamed.exit_status, 2);
  EXPECT_TRUE(contains(unnamed.err, "no column shapex")) << unnamed.err;
  EXPECT_FALSE(fs::exists(path("pairs.txt")));
  // A frame the file does not have.
  const Outcome frame = run("screen --frame 5 " + quoted(data + "/hoomd_triclinic.gsd"));
  EXPECT_EQ(frame.exit_status, 2);
  EXPECT_TRUE(contains(frame.err, "frame 5 is not in the file (it has 1 frames)")) << frame.err;
  // A data file with a zero diameter, named by its line.
  std::ifstream data_in(data + "/lammps_triclinic.data");
  std::string text, line;
  bool done = false;
  bool in_ellipsoids = false;
  int number = 0, changed = 0;
  while (std::getline(data_in, line)) {
    ++number;
    if (line.rfind("Ellipsoids", 0) == 0) in_ellipsoids = true;
    if (in_ellipsoids && !done && !line.empty() &&
        std::isdigit(static_cast<unsigned char>(line[0]))) {
      std::istringstream words(line);
      std::string id;
      words >> id;
      line = id + " 0 0.8 0.6 1 0 0 0";
      changed = number;
      done = true;
    }
    text += line + "\n";
  }
  write_file("zero.data", text);
  const Outcome zero = run("screen zero.data");
  EXPECT_EQ(zero.exit_status, 2);
  EXPECT_TRUE(contains(zero.err, "zero.data:" + std::to_string(changed))) << zero.err;
  // A file that is not there: an input error.
  EXPECT_EQ(run("screen missing.gsd").exit_status, 1);
}

TEST_F(cli, ScreenStopsAtABadLineWithItsNumberAndWritesNothing) {
  write_file("bad.txt", "0 0 0 1 0 0 1 0 1\n# comment\n1 0 0 1 0 0 1 0\n");
  const Outcome short_line = run("screen -o pairs.txt bad.txt");
  EXPECT_EQ(short_line.exit_status, 2);
  EXPECT_TRUE(contains(short_line.err, "bad.txt:3")) << short_line.err;
  EXPECT_FALSE(fs::exists(path("pairs.txt")));
  write_file("indefinite.txt", "0 0 0 1 0 0 1 0 1\n\n1 0 0 1 0 0 1 0 -1\n");
  const Outcome indefinite = run("screen indefinite.txt");
  EXPECT_EQ(indefinite.exit_status, 2);
  EXPECT_TRUE(contains(indefinite.err, "line 3")) << indefinite.err;
  EXPECT_TRUE(contains(indefinite.err, "not positive definite")) << indefinite.err;
  EXPECT_EQ(indefinite.out, "");
  const Outcome small = run("screen --box 3 3 3 indefinite.txt");
  EXPECT_EQ(small.exit_status, 2);
  write_file("two.txt", "0 0 0 1 0 0 1 0 1\n1 0 0 1 0 0 1 0 1\n");
  const Outcome too_small = run("screen --box 3 3 3 two.txt");
  EXPECT_EQ(too_small.exit_status, 2);
  EXPECT_TRUE(contains(too_small.err, "too small")) << too_small.err;
}

// ---------------------------------------------------------------------------
// Reliability: faults, bad input and any size

// Whether this binary runs under AddressSanitizer, which reserves terabytes
// of address space (an address-space limit cannot be set under it) and
// changes resident memory.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool address_sanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool address_sanitizer = true;
#else
constexpr bool address_sanitizer = false;
#endif
#else
constexpr bool address_sanitizer = false;
#endif

TEST_F(cli, ABadInstructionSetInTheEnvironmentIsAUsageErrorForEverySubcommand) {
  // Was: screen aborted (the exception left the search's threads).
  write_file("two.txt", "0 0 0 1 0 0 1 0 1\n1 0 0 1 0 0 1 0 1\n");
  for (const char* command : {"screen two.txt", "demo --n 100", "pairs --pairs 100"}) {
    const Outcome result = run(command, "PWCONTACT_ISA=avx9");
    EXPECT_EQ(result.exit_status, 2) << command << ": " << result.err;
    EXPECT_TRUE(contains(result.err, "PWCONTACT_ISA")) << command << ": " << result.err;
  }
}

TEST_F(cli, AByteThatIsNotPrintableIsShownEscapedInTheMessage) {
  // Was: a NUL cut the message short.
  write_file("nul.txt", std::string("0 0 6 1 0 0 1 0 1 4 0 0 4\0x 0 4\n", 33));
  const Outcome result = run("contact nul.txt");
  EXPECT_EQ(result.exit_status, 2);
  EXPECT_TRUE(contains(result.err, "nul.txt:1: field 13, '4\\x00x', is not a number"))
      << result.err;
}

TEST_F(cli, QuaternionsOfAnyFiniteNormAreTakenAndAZeroOneIsNamed) {
  // Was: norms 1e-161 and 1e154 accepted without a word (their squares
  // underflow or overflow); now they are normalised exactly.
  write_file("small.txt", "0 0 0  0.1 0.1 2  1e-161 0 0 0\n0 0 2.4  0.5 0.5 0.5  1e154 0 0 0\n");
  const Outcome small = run("screen --format axes small.txt");
  ASSERT_EQ(small.exit_status, 0) << small.err;
  EXPECT_EQ(small.out, "0 1\n");
  write_file("zero.txt", "0 0 0  0.1 0.1 2  0 0 0 0\n");
  const Outcome zero = run("screen --format axes zero.txt");
  EXPECT_EQ(zero.exit_status, 2);
  EXPECT_TRUE(contains(zero.err, "line 1")) << zero.err;
  EXPECT_TRUE(contains(zero.err, "(0, 0, 0, 0) is zero")) << zero.err;
}

TEST_F(cli, CentresSpanningMoreThanTheDoubleRangeAreRefusedWithTheirValues) {
  // Was: "cannot create std::vector larger than max_size()".
  write_file("far.txt", "-1e308 0 0 1 0 0 1 0 1\n1e308 0 0 1 0 0 1 0 1\n");
  const Outcome result = run("screen -o pairs.txt far.txt");
  EXPECT_EQ(result.exit_status, 2);
  EXPECT_TRUE(contains(result.err, "from -1e+308 to 1e+308")) << result.err;
  EXPECT_FALSE(fs::exists(path("pairs.txt")));
}

TEST_F(cli, AClosedStandardInputIsNotReusedForTheOutputFile) {
  // Was: with descriptor 0 closed, the output file was opened on it and read
  // back as the input ("0 pairs", exit 0, an empty result).
  write_file("pairs.txt", lines_of({{1, 2, {6, 0, 0}}}));
  const Outcome result = run("contact -o results.txt <&-");
  ASSERT_EQ(result.exit_status, 0) << result.err;
  EXPECT_TRUE(contains(result.err, "0 pairs from <stdin>")) << result.err;
  EXPECT_EQ(read_file("results.txt"), "");
  const Outcome with_input = run("contact pairs.txt -o results.txt <&-");
  ASSERT_EQ(with_input.exit_status, 0) << with_input.err;
  EXPECT_EQ(parse_results(read_file("results.txt")).size(), 1u);
}

// Starts `pwcontact <arguments>` in `directory` with its standard input a
// pipe this process keeps open (so that it waits for more input), and
// returns its process id; the pipe's writing end is in `input`.
pid_t start_waiting_for_input(const fs::path& directory, const std::vector<std::string>& arguments,
                              int& input) {
  int fds[2];
  if (pipe(fds) != 0) return -1;
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[0], 0);
    close(fds[0]);
    close(fds[1]);
    if (chdir(directory.c_str()) != 0) _exit(127);
    std::vector<char*> argv{const_cast<char*>(PWCONTACT_CLI)};
    for (const std::string& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int null = open("/dev/null", O_WRONLY);
    dup2(null, 1);
    dup2(null, 2);
    execv(PWCONTACT_CLI, argv.data());
    _exit(127);
  }
  close(fds[0]);
  input = fds[1];
  return pid;
}

TEST_F(cli, ASignalLeavesNoTemporaryOutputFileBehind) {
  // Was: .NAME.tmp-XXXXXX left beside -o NAME after every abnormal end.
  for (int signal_number : {SIGINT, SIGTERM}) {
    int input = -1;
    const pid_t pid = start_waiting_for_input(path(""), {"contact", "-o", "results.txt"}, input);
    ASSERT_GT(pid, 0);
    const std::string line = lines_of({{1, 2, {6, 0, 0}}});
    ASSERT_EQ(write(input, line.data(), line.size()), ssize_t(line.size()));
    // Wait until the temporary file exists (the output is opened first).
    bool temporary = false;
    for (int k = 0; k < 500 && !temporary; ++k) {
      for (const std::string& name : files()) temporary = temporary || contains(name, ".tmp-");
      if (!temporary) usleep(10000);
    }
    EXPECT_TRUE(temporary) << "the temporary file should exist while the input is read";
    kill(pid, signal_number);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    close(input);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == signal_number) << status;
    for (const std::string& name : files())
      EXPECT_FALSE(contains(name, "results.txt")) << "left behind: " << name;
  }
}

TEST_F(cli, MemoryExhaustionIsOutOfMemoryWithExitStatus1AndNoFileLeft) {
  // Was: std::terminate (SIGABRT) when the search's threads ran out of
  // memory: 20,000 spheres at one point are 2e8 pairs, more than 1 GB.
  if (address_sanitizer) GTEST_SKIP() << "an address-space limit cannot be set under ASan";
  std::string text;
  for (int k = 0; k < 20000; ++k) text += "0 0 0 1 0 0 1 0 1\n";
  write_file("point.txt", text);
  const Outcome result = run("screen -o pairs.txt point.txt", "ulimit -v 1000000 &&");
  EXPECT_EQ(result.exit_status, 1) << result.err;
  EXPECT_TRUE(contains(result.err, "out of memory")) << result.err;
  for (const std::string& name : files()) EXPECT_FALSE(contains(name, "pairs.txt")) << name;
}

TEST_F(cli, ContactStreamsItsInputInBoundedMemory) {
  // Was: the whole input and every column kept (4 GB for 1e7 pairs). Two
  // million pairs (300 MB of text) through a pipe: the resident memory must
  // stay that of a few blocks, below 200 MB (measured ~90 MB).
  if (address_sanitizer) GTEST_SKIP() << "ASan changes resident memory";
  const pwcontact::PairBatch<double> pairs = pwcontact::random_pairs(20000, 7);
  write_file("pairs.txt", pairs_text(pairs));
  const std::string repeat = "for k in $(seq 100); do cat pairs.txt; done |";
  const Outcome result =
      run("contact --outputs mu2 -o results.txt", repeat + " /usr/bin/time -f 'peak %M kB' ");
  ASSERT_EQ(result.exit_status, 0) << result.err;
  EXPECT_TRUE(contains(result.err, "2000000 pairs")) << result.err;
  const double peak_kb = number_after(result.err, "peak ");
  std::printf("[ measured ] contact on 2e6 pairs from a pipe: peak resident memory %.0f MB\n",
              peak_kb / 1024);
  EXPECT_LT(peak_kb, 200 * 1024) << result.err;
  // Every line, in input order.
  std::ifstream out(path("results.txt"));
  std::size_t lines = 0;
  for (std::string line; std::getline(out, line);) ++lines;
  EXPECT_EQ(lines, 2000000u);
}

TEST_F(cli, McReachesItsPackingFractionAndWritesScenesWithNoOverlap) {
  std::vector<std::string> near_pairs;
  for (const char* name : {"mc.gsd", "mc.txt"}) {
    const Outcome mc = run(std::string("mc --n 64 --packing 0.3 --seed 2 -o ") + name);
    ASSERT_EQ(mc.exit_status, 0) << mc.err;
    EXPECT_TRUE(contains(mc.err, "packing fraction 0.3000")) << mc.err;
    EXPECT_TRUE(contains(mc.err, "no overlap")) << mc.err;
    // Read back by screen (the text file with the box its comment gives):
    // no pair overlaps, and some are near contact.
    std::string box;
    if (std::string(name) == "mc.txt") {
      const std::string text = read_file(name);
      const std::size_t at = text.find("--box ");
      ASSERT_NE(at, std::string::npos) << text.substr(0, 300);
      box = "--format axes " + text.substr(at, text.find(" mc.txt", at) - at) + " ";
    }
    const Outcome screen = run("screen " + box + name);
    ASSERT_EQ(screen.exit_status, 0) << screen.err;
    EXPECT_EQ(screen.out, "") << name;
    EXPECT_TRUE(contains(screen.err, "64 ellipsoids")) << screen.err;
    const Outcome near = run("screen --cutoff 1.05 " + box + name);
    EXPECT_NE(near.out, "") << name << ": compressed to contact, some pairs are near";
    near_pairs.push_back(near.out);
  }
  // The GSD file's centres lie in its box as the hoomd schema centres it,
  // [-L/2, L/2) (HOOMD-blue refuses particles outside); the text file's are
  // as the sweeps left them, the same scene: the same near pairs.
  EXPECT_EQ(near_pairs[0], near_pairs[1]);
  const pwcontact::Scene written = pwcontact::read_gsd(path("mc.gsd"));
  for (std::size_t i = 0; i < written.particles.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double half = written.box.length[std::size_t(k)] / 2;
      EXPECT_GE(written.particles.centre(k)[i], -half) << i;
      EXPECT_LT(written.particles.centre(k)[i], half) << i;
    }
  // Falling short: exit status 3, nothing written.
  const Outcome short_of = run("mc --n 216 --packing 0.6 --sweeps 3 -o short.gsd");
  EXPECT_EQ(short_of.exit_status, 3) << short_of.err;
  EXPECT_TRUE(contains(short_of.err, "short of 0.6")) << short_of.err;
  EXPECT_FALSE(fs::exists(path("short.gsd")));
  // Too few for the packing fraction (64 at 0.35: a box of 4.57 against the
  // 4.58 the compression's screens need): refused before the first sweep,
  // a usage error naming the remedy, nothing written. Was: exit status 3
  // sweeps later, with the screen's message about a cutoff never given.
  const Outcome too_few = run("mc --n 64 --packing 0.35 -o few.gsd");
  EXPECT_EQ(too_few.exit_status, 2) << too_few.err;
  EXPECT_TRUE(contains(too_few.err, "64 particles are too few for the packing fraction"))
      << too_few.err;
  EXPECT_TRUE(contains(too_few.err, "take more particles or a lower packing fraction"))
      << too_few.err;
  EXPECT_FALSE(contains(too_few.err, "sweep 1,")) << too_few.err;
  EXPECT_FALSE(fs::exists(path("few.gsd")));
  // One spheroid: the same message (its lattice of one site was narrower
  // than a scene takes, and the scene's own message came first).
  const Outcome one = run("mc --n 1 -o one.gsd");
  EXPECT_EQ(one.exit_status, 2) << one.err;
  EXPECT_TRUE(contains(one.err, "1 particles are too few for the packing fraction")) << one.err;
  EXPECT_FALSE(fs::exists(path("one.gsd")));
}

TEST_F(cli, McWritesItsWholeSceneOrNothingAndChecksItsOutputFirst) {
  // A long path: the text header once went through a 400-character buffer,
  // which cut its last newline and put particle 0 into a comment line.
  const std::string directory(150, 'd');
  fs::create_directory(path(directory));
  const std::string name = directory + "/scene.txt";
  const Outcome mc = run("mc --n 64 --packing 0.2 -o " + name);
  ASSERT_EQ(mc.exit_status, 0) << mc.err;
  const std::string text = read_file(name);
  std::size_t comments = 0, particles = 0;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);)
    ++(line.rfind("#", 0) == 0 ? comments : particles);
  EXPECT_EQ(comments, 3u) << text.substr(0, 600);
  EXPECT_EQ(particles, 64u) << text.substr(0, 600);
  // The command the header gives reads it back whole.
  const std::size_t at = text.find("pwcontact screen ");
  ASSERT_NE(at, std::string::npos);
  const std::size_t from = at + std::string("pwcontact ").size();
  const std::string command = text.substr(from, text.find('\n', at) - from);
  const Outcome screen = run(command);
  ASSERT_EQ(screen.exit_status, 0) << screen.err;
  EXPECT_TRUE(contains(screen.err, "64 ellipsoids")) << screen.err;

  // A path with a space, a quote and a shell's special characters: the
  // header's command quotes it, and a shell reads it back whole.
  fs::create_directory(path("my dir's $(x);"));
  const std::string odd = "my dir's $(x);/scene.txt";
  ASSERT_EQ(run("mc --n 64 --packing 0.2 -o '" + std::string("my dir'\\''s $(x);/scene.txt") + "'")
                .exit_status,
            0);
  const std::string odd_text = read_file(odd);
  const std::size_t odd_at = odd_text.find("pwcontact screen ");
  ASSERT_NE(odd_at, std::string::npos);
  const std::size_t odd_from = odd_at + std::string("pwcontact ").size();
  const Outcome odd_screen = run(odd_text.substr(odd_from, odd_text.find('\n', odd_at) - odd_from));
  ASSERT_EQ(odd_screen.exit_status, 0) << odd_screen.err << odd_text.substr(0, 400);
  EXPECT_TRUE(contains(odd_screen.err, "64 ellipsoids")) << odd_screen.err;

  // A path that cannot be written is refused before the run (an input/output
  // error; it was found after the whole compression).
  const Outcome nowhere = run("mc --n 64 --packing 0.2 -o no/such/directory/scene.gsd");
  EXPECT_EQ(nowhere.exit_status, 1) << nowhere.err;
  EXPECT_TRUE(contains(nowhere.err, "no/such/directory/scene.gsd")) << nowhere.err;
  EXPECT_FALSE(contains(nowhere.err, "no overlap")) << nowhere.err;

  // A write that fails (the shell's file-size limit, its signal ignored):
  // an input/output error, and nothing left behind, for GSD as for text
  // (GSD left a ".partial" file and exited as a usage error).
  for (const char* file : {"limited.gsd", "limited.txt"}) {
    const auto before = std::distance(fs::directory_iterator(path("")), fs::directory_iterator());
    const Outcome limited =
        run(std::string("mc --n 125 --packing 0.2 -o ") + file, "ulimit -f 2 && trap '' XFSZ && ");
    EXPECT_EQ(limited.exit_status, 1) << file << ": " << limited.err;
    EXPECT_TRUE(contains(limited.err, file)) << limited.err;
    EXPECT_FALSE(fs::exists(path(file))) << file;
    const auto after = std::distance(fs::directory_iterator(path("")), fs::directory_iterator());
    EXPECT_EQ(after, before) << file << ": a temporary file was left";
  }
}

// What the shell sets up is kept: the file standard output already is, a
// signal the caller ignores, standard input partly read; the outputs of a
// failed run, and option order. Each was found broken by review.
TEST_F(cli, TheShellsSetUpIsKeptAndAFailedRunLeavesNoOutput) {
  auto shell = [&](const std::string& command) {
    // ("cd ... || exit": with &&, a "&" in the command backgrounded the cd too.)
    const std::string line = "cd " + quoted(path(".").string()) + " || exit 99; " + command;
    const int status = std::system(line.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  const std::string program = quoted(PWCONTACT_CLI);
  write_file("pairs.txt", "3 0 0 1 0 0 1 0 1 1 0 0 1 0 1\n");
  // -o /dev/stdout while the shell appends to a log: the log keeps its lines
  // (was: replaced by a new file holding the result alone).
  write_file("log.txt", "earlier line\n");
  ASSERT_EQ(shell(program + " contact -o /dev/stdout pairs.txt >> log.txt 2>/dev/null"), 0);
  const std::string log = read_file("log.txt");
  EXPECT_EQ(log.rfind("earlier line\n", 0), 0u) << log;
  EXPECT_NE(log.find("2.25"), std::string::npos) << log;
  // A SIGHUP the caller ignores (nohup) stays ignored while an output file
  // is written (was: the run died, exit 129, and lost its output). The input
  // comes through a pipe after the signal, so that the run is under way.
  EXPECT_EQ(shell("{ sleep 1; cat pairs.txt; } | (trap '' HUP; exec " + program +
                  " contact -o hup.txt 2>/dev/null) & pid=$!; sleep 0.3; kill -HUP $pid; "
                  "wait $pid"),
            0);
  EXPECT_NE(read_file("hup.txt").find("2.25"), std::string::npos);
  // Standard input a file whose first line the shell has read: the rest is
  // the input (was: "the file changed while it was read", exit 1).
  write_file("headed.txt", "# a header line\n3 0 0 1 0 0 1 0 1 1 0 0 1 0 1\n");
  EXPECT_EQ(shell("{ read -r header; " + program +
                  " contact > headed_out.txt 2>/dev/null; } < headed.txt"),
            0);
  EXPECT_NE(read_file("headed_out.txt").find("2.25"), std::string::npos);
  // --write-gsd appears only when the run succeeds: not when -o fails
  // (was: the GSD file was committed first).
  const std::string gsd = std::string(PWCONTACT_TEST_DATA) + "/hoomd_triclinic.gsd";
  const Outcome full =
      run("screen --outputs counts --write-gsd full.gsd -o /dev/full " + quoted(gsd));
  EXPECT_EQ(full.exit_status, 1) << full.err;
  EXPECT_FALSE(fs::exists(path("full.gsd")));
  // The frame and the pairs to one place (was: the binary frame appended to
  // the text pairs on standard output): refused before anything is read.
  // (One file by two names too: ./same.txt beside same.txt, -o /dev/stdout
  // beside --write-gsd -.)
  for (const std::string same :
       {"--write-gsd - ", "--write-gsd same.txt -o same.txt ",
        "--write-gsd ./same.txt -o same.txt ", "--write-gsd - -o /dev/stdout "}) {
    const Outcome mixed = run("screen " + same + quoted(gsd));
    EXPECT_EQ(mixed.exit_status, 2) << same;
    EXPECT_EQ(mixed.out, "") << same;
    EXPECT_TRUE(contains(mixed.err, "give the GSD frame and the pairs different places"))
        << mixed.err;
    EXPECT_FALSE(fs::exists(path("same.txt")));
  }
  // The frame to standard output with the pairs in a file: allowed.
  const Outcome apart = run("screen --write-gsd - -o apart.txt " + quoted(gsd));
  EXPECT_EQ(apart.exit_status, 0) << apart.err;
  EXPECT_EQ(apart.out.substr(0, 8), std::string("\xdf\x65\xdf\x65\xdf\x65\xdf\x65", 8))
      << "a GSD file begins with its magic number, 0x65DF65DF65DF65DF little-endian";
  // Repeated --box: the last given, whichever its form (was: --box= won).
  write_file("two.txt", "0 0 0 1 1 1 1 0 0 0\n9 0 0 1 1 1 1 0 0 0\n");
  const Outcome boxes = run("screen --format axes --box=10,10,10 --box 30 30 30 two.txt");
  ASSERT_EQ(boxes.exit_status, 0) << boxes.err;
  EXPECT_EQ(boxes.out, "") << "in a box of 30 the spheres are 9 apart";
  const Outcome boxes_reversed = run("screen --format axes --box 30 30 30 --box=10,10,10 two.txt");
  ASSERT_EQ(boxes_reversed.exit_status, 0) << boxes_reversed.err;
  EXPECT_EQ(boxes_reversed.out, "0 1\n") << "in a box of 10 they are 1 apart";
  // mc -o with an empty name (-o "$UNSET"): a usage error, not silence.
  const Outcome unnamed = run("mc --n 64 -o ''");
  EXPECT_EQ(unnamed.exit_status, 2) << unnamed.err;
  EXPECT_TRUE(contains(unnamed.err, "needs a file name")) << unnamed.err;
}

// Overlap answers of the scalar path in single precision where mu^2 or the
// cutoff's square lies outside float's normal range: decided in double, as
// the batch path decides them (two unit spheres: mu = |r| / 2). Was: mu^2 =
// 9e39 overflowed float and a cutoff of 1e20 answered "apart".
TEST_F(cli, ScalarFloatOverlapAnswersBeyondFloatsRangeAreExact) {
  write_file("far.txt", "1.9e20 0 0 1 0 0 1 0 1 1 0 0 1 0 1\n2.1e20 0 0 1 0 0 1 0 1 1 0 0 1 0 1\n");
  write_file("near.txt",
             "1.9e-20 0 0 1 0 0 1 0 1 1 0 0 1 0 1\n2.1e-20 0 0 1 0 0 1 0 1 1 0 0 1 0 1\n");
  // The overlap answers, each with a valid status (ok, or ok_fallback where
  // the portable target's lanes are the reference path's).
  auto answers = [](const std::string& out) {
    std::string got;
    for (const std::string& line : split_lines(out)) {
      std::istringstream in(line);
      int overlap = -1, status = -1;
      in >> overlap >> status;
      got += std::to_string(overlap) + (status == 0 || status == 1 ? " " : "(invalid) ");
    }
    return got;
  };
  for (const char* path_of : {"", "--scalar "}) {
    const Outcome far = run(std::string("contact --mode overlap --cutoff 1e20 --precision float ") +
                            path_of + "far.txt");
    ASSERT_EQ(far.exit_status, 0) << far.err;
    EXPECT_EQ(answers(far.out), "1 0 ") << path_of << far.out;
    const Outcome near =
        run(std::string("contact --mode overlap --cutoff 1e-20 --precision float ") + path_of +
            "near.txt");
    ASSERT_EQ(near.exit_status, 0) << near.err;
    EXPECT_EQ(answers(near.out), "1 0 ") << path_of << near.out;
  }
}

}  // namespace
